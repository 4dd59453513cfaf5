"""`dualarm report`: the figures and tables of a comparison (paper Figs. 6-8)."""

from __future__ import annotations

import argparse
import sys

from dualarm.cli.arguments import InputPath, OutputDir, positive_int, rate
from dualarm.experiments.run_logs import EVAL_SUCCESS_COLUMNS
from dualarm.task import TARGET_SUCCESS


def cmd_report(args: argparse.Namespace) -> int:
    """Write the report and print one line per condition."""
    from dualarm.experiments.report import save_report
    from dualarm.experiments.summary import build_report

    report = build_report(args.dir, args.window, args.target, args.actors)
    print_report(report, save_report(report, args.output or default_output(args.dir)))
    return 0


def default_output(source):
    """Where a report goes without -o: DIR/report for a comparison, and beside a single run
    (RUN-report), so that no command but ``train`` writes into a run directory."""
    from dualarm.training.run_dir import RunPaths

    if RunPaths(source).config.exists():
        return source.with_name(source.name + "-report")
    return source / "report"


def print_report(report, index) -> None:
    """The findings, then one line per condition, on stdout; the report's notes on stderr;
    and where it is."""
    from dualarm.experiments.findings import findings
    from dualarm.experiments.report import summary_rows

    for line in findings(report):
        print(line)
    header, rows = summary_rows(report)
    for row in rows:
        print("; ".join(f"{h}: {v}" for h, v in zip(header[:8], row[:8])))
    for note in report.notes:
        print(f"note: {note}", file=sys.stderr)
    print(f"wrote {index} (figures, table.md and table.csv beside it)")


def add_report_command(sub) -> None:
    """Add ``report`` to the top-level subparsers."""
    report = sub.add_parser(
        "report", help="figures and tables of a comparison (paper Figs. 6-8)",
        description="Read the training run directories under DIR (config.yaml + metrics.csv, "
                    "up to two levels deep) and write the average return (Fig. 6), success "
                    "(Fig. 7) and time-to-convergence (Fig. 8) figures, table.md, table.csv "
                    "and index.html, with mean and 95 % confidence interval over seeds and the "
                    "paper's values beside them.")
    report.add_argument("dir", type=InputPath, metavar="DIR", help="comparison directory")
    report.add_argument("-o", "--output", type=OutputDir, metavar="OUT",
                        help="output directory (default: DIR/report, or RUN-report beside a "
                             "single run)")
    report.add_argument("--window", type=positive_int, default=100, metavar="N",
                        help="moving-average window, episodes (default: 100)")
    report.add_argument("--target", type=rate, default=TARGET_SUCCESS, metavar="RATE",
                        help="success rate of 'episodes to target' (default: %(default)s)")
    report.add_argument("--actor", "--actors", dest="actors", choices=tuple(EVAL_SUCCESS_COLUMNS),
                        default="policy",
                        help="evaluations to read: each run's policy (eval.csv success_rate, "
                             "the default) or the averaged actors evaluated beside it "
                             "(average_success_rate; runs with algo.policy_average > 0); "
                             "--actors is the older spelling")
    report.set_defaults(func=cmd_report)
