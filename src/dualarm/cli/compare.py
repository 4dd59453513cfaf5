"""`dualarm compare`: every condition x seed of the training run, in parallel and resumable."""

from __future__ import annotations

import argparse
import sys

from dualarm.cli.arguments import InputPath, OutputDir, positive, positive_int, stop_rate
from dualarm.task import TARGET_SUCCESS


def cmd_compare(args: argparse.Namespace) -> int:
    """Prepare (or reopen) the comparison in -o DIR and train its unfinished runs.

    Exit status: 0 when every run finished, 1 when a run failed, 130 when interrupted.
    """
    from dualarm.experiments.backends import make_backend
    from dualarm.experiments.compare import compare

    request = compare_request(args, constraints_dir=args.constraints_dir, demos_dir=args.demos)
    backend = make_backend(args.backend, args.workers, args.ray_address)
    try:
        result = compare(args.output, request, backend, poll_s=args.poll)
    except KeyboardInterrupt:
        print(f"\nstopped; run the same command again to resume the runs in {args.output}",
              file=sys.stderr)
        return 130
    failed = result.failed
    done = len(result.outcomes) - len(failed)
    print(f"{done} run(s) trained, {len(result.skipped)} already finished, {len(failed)} failed"
          + (f" ({', '.join(o.name for o in failed)}); run the same command again to retry them"
             if failed else "")
          + f"; runs in {result.comparison.root / 'runs'}")
    return 1 if failed else 0


def compare_request(args: argparse.Namespace, constraints_dir=None, demos_dir=None):
    """The ``CompareRequest`` of ``grid_options`` and ``--episodes`` as parsed."""
    from dualarm.experiments.compare import CompareRequest, parse_conditions, parse_seeds
    from dualarm.training import TrainConfig

    return CompareRequest(
        conditions=parse_conditions(args.conditions) if args.conditions is not None else None,
        seeds=parse_seeds(args.seeds) if args.seeds is not None else None,
        episodes=args.episodes,
        base=TrainConfig.load(args.config) if args.config is not None else None,
        base_source=str(args.config),
        constraints_dir=constraints_dir, demos_dir=demos_dir, stop_at=args.stop_at)


def grid_options(p: argparse.ArgumentParser, seeds: str = "0,1,2",
                 workers: str = "the CPU count", conditions: str = "the paper's three",
                 stop: str = "the --config's, none in the recipe") -> None:
    """The options that say which runs to train and where: shared by compare and pipeline,
    which hands them on to compare (None: the comparison's, or the command's default, which
    ``seeds``, ``workers`` and ``conditions`` name in the help)."""
    p.add_argument("--conditions", metavar="C1,C2,...",
                   help="among none, single, multi (the paper's) and demos (the recordings "
                        f"as demonstrations, with the multi constraints; default: {conditions}, "
                        "or the comparison's)")
    p.add_argument("--seeds", metavar="S1,S2,...",
                   help=f"seeds, integers in 0..2**32 - 1 (default: {seeds}, or the comparison's)")
    p.add_argument("--workers", type=positive_int, metavar="W",
                   help=f"runs at a time (default local: {workers}; ray: as many as the "
                        "cluster has CPUs for)")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local worker processes, or Ray tasks (default: local)")
    p.add_argument("--ray-address", metavar="ADDR",
                   help="Ray cluster to submit to, e.g. auto or ray://HOST:10001 (default: start "
                        "a local Ray instance)")
    p.add_argument("--stop-at", type=stop_rate, metavar="RATE|none",
                   help=f"end each run after the first evaluation whose success reaches RATE "
                        f"(TrainConfig.stop_at; the report's target is {TARGET_SUCCESS:g}); none: "
                        f"every run trains all its episodes (default: {stop}, or the comparison's)")
    p.add_argument("--config", type=InputPath, metavar="BASE.yaml|paper",
                   help="TrainConfig fields for every run, or a preset (as `dualarm train "
                        "--config`); condition, seed and constraints are set per run. Default: "
                        "the recipe, as `dualarm train` uses it")


def add_compare_command(sub) -> None:
    """Add ``compare`` to the top-level subparsers."""
    p = sub.add_parser(
        "compare", help="train every condition x seed (parallel, resumable)",
        description="Train one run of `dualarm train` per (condition, seed) in parallel, in "
                    "DIR/runs/CONDITION-seedSEED, with the settings recorded in "
                    "DIR/comparison.yaml. Run it again to skip the finished runs and resume the "
                    "others; a larger --episodes extends them, new --conditions or --seeds add "
                    "runs. See docs/compare.md.")
    grid_options(p)
    p.add_argument("--episodes", type=positive_int, metavar="N",
                   help="training episodes per run (default: the --config's, the recipe's 10000, "
                        "or the comparison's; a larger value extends the runs)")
    p.add_argument("--constraints-dir", type=InputPath, metavar="DIR",
                   help="folder with single.yaml and multi.yaml (`dualarm constraints extract` "
                        "output; default: the shipped constraint files)")
    p.add_argument("--demos", type=InputPath, metavar="DIR",
                   help="a demonstration folder (recordings with gripper events, labels.csv, "
                        "scene.csv) for the demos condition, which it adds (default for "
                        "--conditions ...,demos: the shipped set, src/dualarm/data/demos)")
    p.add_argument("--poll", type=positive, default=2.0, metavar="S",
                   help=argparse.SUPPRESS)
    p.add_argument("-o", "--output", type=OutputDir, required=True, metavar="DIR",
                   help="comparison directory")
    p.set_defaults(func=cmd_compare)
