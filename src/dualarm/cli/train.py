"""`dualarm train`: learn the task (start a run, or resume one)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from dualarm.cli.arguments import InputPath, OutputDir, positive_int
from dualarm.errors import InputError
from dualarm.task import CONDITIONS


def cmd_train(args: argparse.Namespace) -> int:
    """Start a run (or resume one with --resume) and report where it ended."""
    from dualarm.training import Trainer, TrainConfig

    if args.resume:
        ignored = [name for name in ("condition", "constraints", "seed", "out", "num_envs", "config",
                                     "demos")
                   if getattr(args, name) is not None]
        if ignored:
            print(f"dualarm: note: --resume keeps the run's own settings; ignoring "
                  f"{', '.join('--' + n.replace('_', '-') for n in ignored)}", file=sys.stderr)
        trainer = Trainer.resume(args.resume, episodes=args.episodes)
        print(f"resuming {args.resume} at episode {trainer.episodes} of {trainer.config.episodes}",
              file=sys.stderr)
    else:
        changes = {k: v for k, v in (("condition", args.condition), ("episodes", args.episodes),
                                     ("seed", args.seed), ("num_envs", args.num_envs)) if v is not None}
        if args.constraints is not None:
            changes["constraints"] = str(args.constraints)
        if args.demos is not None:
            changes["demos"] = str(Path(args.demos).resolve())
        # the command line's options complete the file's before the whole is checked
        config = TrainConfig.load(args.config, changes) if args.config else \
            TrainConfig.from_dict(changes, where="the command line")
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
    if result.stopped:
        line += f" (stopped: evaluation success reached stop_at {trainer.config.stop_at:g})"
    if result.last_eval:
        line += (f"; last evaluation: success {result.last_eval['success_rate']:.2f}, "
                 f"return {result.last_eval['return_mean']:.1f}")
    print(line)
    print(f"run directory: {result.out} (metrics.csv, eval.csv, {curves.name}, events/ for TensorBoard)")
    return 0


def add_train_command(sub) -> None:
    """Add ``train`` to the top-level subparsers."""
    train = sub.add_parser("train", help="train DADDPG on the Baxter task (resumable)",
                           description="Train the dual-agent DDPG on the reach-grasp-align task. "
                                       "Writes config.yaml, metrics.csv, eval.csv, TensorBoard "
                                       "events and checkpoints to the run directory.")
    train.add_argument("--condition", choices=CONDITIONS,
                       help="joint-angle guidance (default: multi, with the shipped constraints)")
    train.add_argument("--constraints", type=InputPath, metavar="FILE.yaml",
                       help="constraints file for single/multi (default: the shipped one)")
    train.add_argument("--episodes", type=positive_int, help="training episodes in all (default: the recipe's 10000)")
    train.add_argument("--seed", type=int, help="seed of the run (default: 0)")
    train.add_argument("--num-envs", type=positive_int, help="environment copies stepped together (default: 16)")
    train.add_argument("-o", "--output", "--out", dest="out", type=OutputDir, metavar="DIR",
                       help="run directory (default: runs/CONDITION-seedSEED; --out is the "
                            "older spelling)")
    train.add_argument("--config", type=InputPath, metavar="FILE.yaml|paper",
                       help="training settings: a YAML file of any fields of a run's config.yaml "
                            "(the fields it leaves out take the recipe's, or a preset's with "
                            "`extends: paper`; the options above override them), or a preset: "
                            "recipe (the default, TrainConfig()) or paper (the paper's plain DDPG)")
    train.add_argument("--demos", type=InputPath, metavar="DIR",
                       help="a demonstration folder (recordings with gripper events, labels.csv, "
                            "scene.csv; the shipped set is src/dualarm/data/demos): its recordings, "
                            "replayed at their own scenes and moved to the config's demos.episodes "
                            "(default 256) new placements, fill a demonstration buffer with "
                            "Q-filtered behaviour cloning: 64 rows per update and bc_weight 1 "
                            "(DEMOS_ALGO) where the config keeps a preset's values. Default: "
                            "none, as in the paper")
    train.add_argument("--resume", type=InputPath, metavar="DIR",
                       help="continue the run in DIR from its last checkpoint")
    train.set_defaults(func=cmd_train)
