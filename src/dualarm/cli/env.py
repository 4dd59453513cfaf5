"""`dualarm env ...`: look at the Baxter task, its scripted expert and its speed."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from dualarm.cli.arguments import (InputPath, OutputFile, VideoFile, frame_rate, pixels, positive_int,
                                   seed_number)
from dualarm.task import CONDITIONS


def _environment(args: argparse.Namespace):
    """The task core from the command's options (frame size too, for rendering commands)."""
    from dualarm.envs import make_core

    constraints = args.constraints
    if constraints is None and args.condition != "none":      # the shipped set, as train uses
        from dualarm.constraints.constraint_set import default_constraints_path

        constraints = default_constraints_path(args.condition)
    env = make_core(condition=args.condition, constraints=constraints, control=args.control)
    if hasattr(args, "height"):
        env.render_size = (args.height, args.width)
    return env


def _progress(iterable, total: int, desc: str):
    from tqdm import tqdm

    return tqdm(iterable, total=total, desc=desc, unit="ep", file=sys.stderr)


def cmd_env_video(args: argparse.Namespace) -> int:
    """Render episodes of a policy to an MP4 (or GIF)."""
    from dualarm.envs.rendering import write_video
    from dualarm.envs.rollout import make_policy, run_episode

    env = _environment(args)
    policy = make_policy(args.policy, env, args.seed)
    frames = []
    for k in _progress(range(args.episodes), args.episodes, "episodes"):
        episode = run_episode(env, policy, args.seed + k, camera=args.camera)
        frames.extend(with_end_pause(episode.frames, args.fps))
        print(f"episode {k + 1} (seed {args.seed + k}): {'success' if episode.success else 'failure'} "
              f"in {episode.steps} steps, returns left {episode.returns[0]:.1f} right "
              f"{episode.returns[1]:.1f}", file=sys.stderr)
    path = write_video(args.output, frames, fps=args.fps)
    env.close()
    speed = args.fps * env.config.control_period
    print(f"wrote {path} ({len(frames)} frames, {len(frames) / args.fps:.1f} s at {speed:.2g}x real time)")
    return 0


def cmd_env_expert(args: argparse.Namespace) -> int:
    """Success rate of the scripted expert over seeded episodes."""
    from dualarm.envs.rollout import make_policy, run_episode

    env = _environment(args)
    policy = make_policy("expert", env)
    episodes = [run_episode(env, policy, args.seed + k)
                for k in _progress(range(args.episodes), args.episodes, "expert")]
    success = np.array([e.success for e in episodes])
    steps = np.array([e.steps for e in episodes])
    returns = np.array([e.returns for e in episodes])
    print(f"scripted expert, {args.episodes} episodes (seeds {args.seed}..{args.seed + args.episodes - 1}), "
          f"condition {args.condition}:")
    print(f"  success rate  {success.mean():.3f} ({success.sum()}/{len(success)})")
    print(f"  steps         mean {steps.mean():.1f}, max {steps.max()} (limit {env.config.max_episode_steps})")
    print(f"  return        left {returns[:, 0].mean():.1f}, right {returns[:, 1].mean():.1f} (mean)")
    failed = [e.seed for e in episodes if not e.success]
    if failed:
        print(f"  failed seeds  {failed[:20]}{' ...' if len(failed) > 20 else ''}")
    return 0


def cmd_env_strip(args: argparse.Namespace) -> int:
    """A strip of frames of one expert episode (PNG)."""
    import imageio.v3 as iio

    from dualarm.atomic import atomic_open
    from dualarm.envs.rollout import make_policy, run_episode

    env = _environment(args)
    episode = run_episode(env, make_policy(args.policy, env, args.seed), args.seed, camera=args.camera)
    picks = np.linspace(0, len(episode.frames) - 1, args.frames).round().astype(int)
    strip = np.concatenate([episode.frames[i] for i in picks], axis=1)
    out = Path(args.output)
    with atomic_open(out) as f:
        iio.imwrite(f, strip, extension=".png")
    print(f"wrote {out}: steps {', '.join(str(int(i)) for i in picks)} of {episode.steps}")
    return 0


def frame_options(p: argparse.ArgumentParser) -> None:
    """--camera, --width and --height of commands that render frames."""
    p.add_argument("--camera", choices=("front", "side"), default="front",
                   help="the camera rendering the scene (default: front)")
    p.add_argument("--width", type=pixels, default=640, help="frame width in pixels (default 640)")
    p.add_argument("--height", type=pixels, default=480, help="frame height in pixels (default 480)")


def with_end_pause(frames: list, fps: float) -> list:
    """The frames with the last one held for 0.6 s, so a video does not end abruptly."""
    return frames + [frames[-1]] * int(0.6 * fps)


def add_env_command(sub) -> None:
    """Add the ``env`` command group to the top-level subparsers."""
    env = sub.add_parser("env", help="the Baxter reach-grasp-align task: videos, expert, frames",
                         description="The MuJoCo Baxter reach-grasp-align task.")
    esub = env.add_subparsers(dest="env_command", required=True, metavar="COMMAND")

    def task_options(p: argparse.ArgumentParser) -> None:
        p.add_argument("--condition", choices=CONDITIONS, default="multi",
                       help="joint-angle guidance (default: multi, with the shipped constraints, "
                            "as train)")
        p.add_argument("--constraints", type=InputPath, metavar="FILE.yaml",
                       help="constraints file for single/multi (default: the shipped one)")
        p.add_argument("--control", choices=("cartesian", "joint"), default="cartesian",
                       help="action space (default: cartesian)")
        p.add_argument("--seed", type=seed_number, default=0, help="seed of the first episode (default: 0)")

    def rendering_options(p: argparse.ArgumentParser) -> None:
        p.add_argument("--policy", choices=("expert", "random"), default="expert",
                       help="who acts: the scripted expert or uniform random actions (default: expert)")
        frame_options(p)

    video = esub.add_parser("video", help="render episodes of a policy to MP4 or GIF",
                            description="Run episodes of a policy and write them as a video.")
    task_options(video)
    rendering_options(video)
    video.add_argument("--episodes", type=positive_int, default=2,
                       help="episodes, one after the other in the video (default: 2)")
    video.add_argument("--fps", type=frame_rate, default=12.0,
                       help="frames per second of the video; one frame per step, so the default "
                            "plays at 0.24x real time (a step is 20 ms)")
    video.add_argument("-o", "--output", type=VideoFile, required=True, metavar="FILE.mp4|.gif",
                       help="the video to write")
    video.set_defaults(func=cmd_env_video)

    expert = esub.add_parser("expert", help="success rate of the scripted expert",
                             description="Run the scripted expert over seeded episodes and report "
                                         "its success rate, episode length and returns.")
    task_options(expert)
    expert.add_argument("--episodes", type=positive_int, default=200,
                        help="seeded episodes to run (default: 200)")
    expert.set_defaults(func=cmd_env_expert)

    strip = esub.add_parser("strip", help="a strip of frames of one episode (PNG)",
                            description="Render one episode and put evenly spaced frames side by side.")
    task_options(strip)
    rendering_options(strip)
    strip.add_argument("--frames", type=positive_int, default=5,
                       help="frames in the strip, evenly spaced over the episode (default: 5)")
    strip.add_argument("-o", "--output", type=OutputFile, required=True, metavar="FILE.png",
                       help="the PNG to write")
    strip.set_defaults(func=cmd_env_strip)
