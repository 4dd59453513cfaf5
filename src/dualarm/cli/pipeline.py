"""`dualarm pipeline`: built-in demonstrations -> constraints -> comparison -> report, in one go."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from dualarm.cli.arguments import InputPath, OutputDir, positive_int
from dualarm.cli.compare import compare_request, grid_options
from dualarm.cli.report import print_report
from dualarm.demos.formats import LABELS_NAME, SCENE_NAME
from dualarm.task import TARGET_SUCCESS


def cmd_pipeline(args: argparse.Namespace) -> int:
    """Run every step (:func:`dualarm.experiments.pipeline.run_pipeline`); stop at the first
    that fails. Exit status 2 for bad input (the step's error, from ``main``), 1 when a run
    failed, 130 when interrupted."""
    from dualarm.experiments.backends import make_backend
    from dualarm.experiments.pipeline import (PipelineStopped, pipeline_request, planned_grid,
                                              run_pipeline)

    request = pipeline_request(args.output, compare_request(args), args.demo_dir)
    workers = args.workers
    if workers is None and args.backend == "local":
        # every run at once, even past the core count: the runs are equally long, so R runs
        # sharing C cores end after R/C run-times where C at a time take ceil(R/C)
        conditions, seeds = planned_grid(args.output, request)
        workers = max(os.cpu_count() or 1, len(conditions) * len(seeds))
    backend = make_backend(args.backend, workers, args.ray_address)
    again = "run the same command again to resume"
    try:
        result = run_pipeline(args.output, request, backend, args.demo_dir)
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
                    "report`). Run it again to resume. Every run uses the recipe "
                    "(TrainConfig's defaults) unless --config says otherwise. Beside the paper's "
                    "three conditions, the demos condition learns from the recordings "
                    "themselves as demonstrations (with the multi constraints). The defaults "
                    "(one seed per condition, 6000 episodes, all runs at once, each run ending "
                    "at the evaluation that reaches 0.85 success) are long enough for every "
                    "condition to learn; --episodes 10000 --seeds 0,1,2,3,4 is the full "
                    "reproduction.")
    p.add_argument("-o", "--output", type=OutputDir, default=Path("out/pipeline"), metavar="DIR",
                   help="output directory (default: out/pipeline)")
    p.add_argument("--episodes", type=positive_int, metavar="N",
                   help="training episodes per run (default for a new comparison: 6000, or the "
                        "--config's; then the comparison's; a larger value extends the runs)")
    grid_options(p, seeds="0", workers="as many as there are runs, at least the CPU count",
                 conditions="the paper's three and demos where the demonstrations have their "
                            "scene file", stop=f"{TARGET_SUCCESS:g} for a new comparison")
    p.add_argument("--demos", "--demo-dir", dest="demo_dir", type=InputPath, metavar="DIR",
                   help=f"demonstrations with {LABELS_NAME}, and {SCENE_NAME} for the demos "
                        "condition (default: the shipped ones; --demo-dir is the older spelling)")
    p.set_defaults(func=cmd_pipeline)
