"""`dualarm train | eval | play`: learn the task, and use what was learned."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


from dualarm.cli_types import InputPath, OutputDir, OutputFile, positive_int
from dualarm.errors import InputError
from dualarm.task import CONDITIONS


def cmd_train(args: argparse.Namespace) -> int:
    """Start a run (or resume one with --resume) and report where it ended."""
    from dualarm.training import Trainer, TrainConfig

    if args.resume:
        ignored = [name for name in ("condition", "constraints", "seed", "out", "num_envs", "config")
                   if getattr(args, name) is not None]
        if ignored:
            print(f"dualarm: note: --resume keeps the run's own settings; ignoring "
                  f"{', '.join('--' + n.replace('_', '-') for n in ignored)}", file=sys.stderr)
        trainer = Trainer.resume(args.resume, episodes=args.episodes)
        print(f"resuming {args.resume} at episode {trainer.episodes} of {trainer.config.episodes}",
              file=sys.stderr)
    else:
        config = TrainConfig.load(args.config) if args.config else TrainConfig()
        changes = {k: v for k, v in (("condition", args.condition), ("episodes", args.episodes),
                                     ("seed", args.seed), ("num_envs", args.num_envs)) if v is not None}
        if args.constraints is not None:
            changes["constraints"] = str(args.constraints)
        config = config.with_(**changes)
        if config.condition == "none" and config.constraints:
            raise InputError("--constraints needs --condition single or multi")
        out = args.out or Path("runs") / f"{config.condition}-seed{config.seed}"
        trainer = Trainer.start(config, out)
    try:
        result = trainer.run()
    except KeyboardInterrupt:
        print(f"\nstopped; continue with: dualarm train --resume {trainer.paths.root}",
              file=sys.stderr)
        return 130
    finally:
        trainer.close()
    from dualarm.training.plots import plot_run

    curves = plot_run(result.out, trainer.paths.curves)
    line = f"done: {result.episodes} episodes, {result.env_steps} steps, {result.wall_time_s:.0f} s"
    if result.last_eval:
        line += (f"; last evaluation: success {result.last_eval['success_rate']:.2f}, "
                 f"return {result.last_eval['return_mean']:.1f}")
    print(line)
    print(f"run directory: {result.out} (metrics.csv, eval.csv, {curves.name}, events/ for TensorBoard)")
    return 0


def cmd_eval(args: argparse.Namespace) -> int:
    """Success rate and mean return of a run's policy on the fixed evaluation episodes."""
    from dualarm.training.evaluation import evaluate
    from dualarm.training.loop import make_vector_env
    from dualarm.training.policy import load_policy

    config, agent, info = load_policy(args.run, args.checkpoint)
    vec = make_vector_env(config, min(config.num_envs, args.episodes))
    result = evaluate(lambda o: agent.act(o), vec, args.episodes)
    print(f"{info['checkpoint']} (after {info['episodes']} training episodes), "
          f"{args.episodes} evaluation episodes:")
    print(f"  success rate  {result.success_rate:.3f} ({int(result.success.sum())}/{args.episodes})")
    print(f"  return        {result.mean_return:.1f} (mean, both arms)")
    print(f"  steps         {result.steps.mean():.1f} (mean)")
    return 0


def policy_episode(run: Path, checkpoint: str, seed: int, camera: str | None = None,
                   size: tuple[int, int] | None = None):
    """One episode of a run's deterministic policy from ``reset(seed)``.
    Returns (env, episode, checkpoint info)."""
    from dualarm.envs.baxter import BaxterReachGraspAlign
    from dualarm.envs.rollout import run_episode
    from dualarm.training.policy import load_policy, single_env_policy

    config, agent, info = load_policy(run, checkpoint)
    env = BaxterReachGraspAlign(config.task_config(), config.load_constraints())
    if size:
        env.render_size = size
    episode = run_episode(env, single_env_policy(agent), seed, camera=camera)
    env.close()
    return env, episode, info


def cmd_play(args: argparse.Namespace) -> int:
    """Render an episode of the learned policy to MP4 or GIF."""
    from dualarm.cli_env import with_end_pause
    from dualarm.envs.rendering import write_video

    env, episode, info = policy_episode(args.run, args.checkpoint, args.seed, args.camera,
                                           (args.height, args.width))
    frames = with_end_pause(episode.frames, args.fps)
    path = write_video(args.output, frames, fps=args.fps)
    print(f"{info['checkpoint']}: seed {args.seed}, {'success' if episode.success else 'failure'} in "
          f"{episode.steps} steps, returns left {episode.returns[0]:.1f} right {episode.returns[1]:.1f}")
    print(f"wrote {path} ({len(frames)} frames)")
    return 0


def add_train_commands(sub) -> None:
    """Add ``train``, ``eval`` and ``play`` to the top-level subparsers."""
    from dualarm.cli_env import frame_options

    train = sub.add_parser("train", help="train DADDPG on the Baxter task (resumable)",
                           description="Train the dual-agent DDPG on the reach-grasp-align task. "
                                       "Writes config.yaml, metrics.csv, eval.csv, TensorBoard "
                                       "events and checkpoints to the run directory.")
    train.add_argument("--condition", choices=CONDITIONS,
                       help="joint-angle guidance (default: multi, with the shipped constraints)")
    train.add_argument("--constraints", type=InputPath, metavar="FILE.yaml",
                       help="constraints file for single/multi (default: the shipped one)")
    train.add_argument("--episodes", type=positive_int, help="training episodes in all (default: 3000)")
    train.add_argument("--seed", type=int, help="seed of the run (default: 0)")
    train.add_argument("--num-envs", type=positive_int, help="environment copies stepped together (default: 16)")
    train.add_argument("--out", type=OutputDir, metavar="DIR",
                       help="run directory (default: runs/CONDITION-seedSEED)")
    train.add_argument("--config", type=InputPath, metavar="FILE.yaml",
                       help="training settings (any fields of a run's config.yaml; the "
                            "options above override them)")
    train.add_argument("--resume", type=InputPath, metavar="DIR",
                       help="continue the run in DIR from its last checkpoint")
    train.set_defaults(func=cmd_train)

    def run_options(p: argparse.ArgumentParser) -> None:
        p.add_argument("run", type=InputPath, metavar="DIR", help="a run directory of dualarm train")
        p.add_argument("--checkpoint", choices=("best", "latest"), default="best",
                       help="the best evaluated policy or the last checkpoint (default: best)")

    ev = sub.add_parser("eval", help="success rate and return of a trained policy",
                        description="Evaluate a run's policy on the fixed set of evaluation episodes.")
    run_options(ev)
    ev.add_argument("--episodes", type=int, default=100)
    ev.set_defaults(func=cmd_eval)

    play = sub.add_parser("play", help="render the learned policy to MP4 or GIF",
                          description="Render one episode of a run's policy.")
    run_options(play)
    play.add_argument("-o", "--output", type=OutputFile, required=True, metavar="FILE.mp4")
    play.add_argument("--seed", type=int, default=0)
    frame_options(play)
    play.add_argument("--fps", type=float, default=12.0)
    play.set_defaults(func=cmd_play)
