"""`dualarm pipeline`: built-in demonstrations -> constraints -> comparison -> report, in one go."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from dualarm.cli.arguments import InputPath, OutputDir, positive_int
from dualarm.cli.compare import compare_request, grid_options
from dualarm.cli.report import print_report
from dualarm.demos.formats import LABELS_NAME


def cmd_pipeline(args: argparse.Namespace) -> int:
    """Run every step (:func:`dualarm.experiments.pipeline.run_pipeline`); stop at the first
    that fails. Exit status 2 for bad input (the step's error, from ``main``), 1 when a run
    failed, 130 when interrupted."""
    from dualarm.experiments.backends import make_backend
    from dualarm.experiments.pipeline import PipelineStopped, run_pipeline

    backend = make_backend(args.backend, args.workers, args.ray_address)
    again = "run the same command again to resume"
    try:
        result = run_pipeline(args.output, compare_request(args), backend, args.demo_dir)
    except KeyboardInterrupt:
        print(f"\nstopped; {again} the runs in {args.output}", file=sys.stderr)
        return 130
    except PipelineStopped as stop:
        print(f"dualarm: {stop}; {again}", file=sys.stderr)
        raise stop.__cause__ from None      # main turns bad input into one line and exit 2
    if result.report is None:
        failed = ", ".join(o.name for o in result.comparison.failed)
        print(f"dualarm: pipeline stopped at the training step: run(s) {failed} failed; {again}",
              file=sys.stderr)
        return 1
    print_report(result.report, result.report_index)
    print(f"done: open {result.report_index}", file=sys.stderr)
    return 0


def add_pipeline_command(sub) -> None:
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
                   help="training episodes per run (default: 200, about 12 minutes on 2 cores)")
    grid_options(p)
    p.add_argument("--demo-dir", type=InputPath, metavar="DIR",
                   help=f"demonstrations with {LABELS_NAME} (default: the shipped ones)")
    p.set_defaults(func=cmd_pipeline)
