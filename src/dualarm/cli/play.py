"""`dualarm play`: render an episode of a run's learned policy."""

from __future__ import annotations

import argparse

from dualarm.cli.arguments import VideoFile, frame_rate, run_options, seed_number
from dualarm.cli.env import frame_options, with_end_pause


def cmd_play(args: argparse.Namespace) -> int:
    """Render an episode of the learned policy to MP4 or GIF."""
    from dualarm.training.policy import policy_episode
    from dualarm.envs.rendering import write_video

    env, episode, info = policy_episode(args.run, args.checkpoint, args.seed, args.camera,
                                        (args.height, args.width), progress=True)
    frames = with_end_pause(episode.frames, args.fps)
    path = write_video(args.output, frames, fps=args.fps)
    print(f"{info['checkpoint']}: seed {args.seed}, {'success' if episode.success else 'failure'} in "
          f"{episode.steps} steps, returns left {episode.returns[0]:.1f} right {episode.returns[1]:.1f}")
    print(f"wrote {path} ({len(frames)} frames)")
    return 0


def add_play_command(sub) -> None:
    """Add ``play`` to the top-level subparsers."""
    play = sub.add_parser("play", help="render the learned policy to MP4 or GIF",
                          description="Render one episode of a run's policy.")
    run_options(play)
    play.add_argument("-o", "--output", type=VideoFile, required=True, metavar="FILE.mp4|.gif",
                      help="the video to write")
    play.add_argument("--seed", type=seed_number, default=0, help="the episode's reset seed (default 0)")
    frame_options(play)
    play.add_argument("--fps", type=frame_rate, default=12.0,
                      help="frames per second of the video (default 12)")
    play.set_defaults(func=cmd_play)
