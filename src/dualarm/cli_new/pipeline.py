"""`dualarm pipeline`: built-in demonstrations -> constraints -> comparison -> report, in one go."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from dualarm.cli_experiments import grid_argv, grid_options
from dualarm.cli_types import InputPath, OutputDir, positive_int

#: (condition, segment spec) of the constraint files the comparison needs (paper: C1, C2&C3).
CONSTRAINT_SETS = (("single", "reach+grasp+align"), ("multi", "reach+grasp,align"))


def pipeline_steps(args: argparse.Namespace) -> list[tuple[str, list[str]]]:
    """The `dualarm` commands the pipeline runs, in order, as (title, argv)."""
    out: Path = args.output
    constraints = out / "constraints"
    steps = []
    for name, spec in CONSTRAINT_SETS:
        argv = ["constraints", "extract", "--segments", spec, "--name", name,
                "-o", str(constraints / f"{name}.yaml")]
        if args.demo_dir is not None:
            argv.insert(2, str(args.demo_dir))
        steps.append((f"constraints {name} ({spec}) from the demonstrations", argv))
    compare = ["compare", "--episodes", str(args.episodes), *grid_argv(args),
               "--constraints-dir", str(constraints), "-o", str(out)]
    steps.append((f"training: conditions {args.conditions or 'none,single,multi'} x seeds "
                  f"{args.seeds or '0,1,2'}, {args.episodes} episodes each", compare))
    steps.append(("report: Figs. 6-8, table, HTML", ["report", str(out)]))
    return steps


def cmd_pipeline(args: argparse.Namespace) -> int:
    """Run every step; stop at the first that fails (its exit status is returned).

    Running it again resumes: constraint files are re-extracted (seconds, identical), the
    comparison skips finished runs and resumes partial ones, the report is rewritten.
    """
    from dualarm.cli import main

    steps = pipeline_steps(args)
    for k, (title, argv) in enumerate(steps, 1):
        print(f"[{k}/{len(steps)}] {title}\n        dualarm {' '.join(argv)}", file=sys.stderr)
        status = main(argv)
        if status:
            print(f"dualarm: pipeline stopped at step {k} ({title}); run the same command again "
                  "to resume", file=sys.stderr)
            return status
    print(f"done: open {args.output / 'report' / 'index.html'}", file=sys.stderr)
    return 0


def add_pipeline_commands(sub) -> None:
    """Add ``pipeline`` to the top-level subparsers."""
    p = sub.add_parser(
        "pipeline", help="demonstrations -> constraints -> comparison -> report",
        description="The whole experiment on built-in data: extract the single (C1) and multi "
                    "(C2&C3) constraints from the shipped demonstrations, train every "
                    "condition x seed (`dualarm compare`), and write the report (`dualarm "
                    "report`). Run it again to resume. The defaults are a short first run; "
                    "--episodes 10000 reproduces the paper's budget.")
    p.add_argument("-o", "--output", type=OutputDir, default=Path("out/pipeline"), metavar="DIR",
                   help="output directory (default: out/pipeline)")
    p.add_argument("--episodes", type=positive_int, default=200, metavar="N",
                   help="training episodes per run (default: 200, about 9 minutes on 2 cores)")
    grid_options(p)
    p.add_argument("--demo-dir", type=InputPath, metavar="DIR",
                   help="demonstrations with labels.csv (default: the shipped ones)")
    p.set_defaults(func=cmd_pipeline)
