"""The `dualarm` entry point: the parser of every top-level command, and one line per expected error."""

from __future__ import annotations

import argparse
import sys
import warnings

from dualarm import __version__
from dualarm.cli import (compare, constraints, demos, diagnose, env, evaluate, export, mocap,
                         pipeline, play, quickstart, report, train)
from dualarm.cli.arguments import check_paths, option_names
from dualarm.errors import DualarmError

#: The top-level commands' modules, in the order ``dualarm --help`` lists them.
COMMANDS = (quickstart.add_quickstart_command, mocap.add_mocap_command, env.add_env_command,
            demos.add_demos_command, constraints.add_constraints_command, train.add_train_command,
            evaluate.add_eval_command, diagnose.add_diagnose_command, play.add_play_command,
            export.add_export_command, report.add_report_command, compare.add_compare_command,
            pipeline.add_pipeline_command)


def build_parser() -> argparse.ArgumentParser:
    """The ``dualarm`` parser with every top-level command."""
    parser = argparse.ArgumentParser(
        prog="dualarm",
        description="Human IMU demonstrations -> joint-angle constraints -> dual-arm reinforcement learning.")
    parser.add_argument("--version", action="version", version=f"dualarm {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add_command in COMMANDS:
        add_command(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point: parse ``argv``, run the subcommand, turn expected errors into one line."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        check_paths(args, option_names(parser))
        with warnings.catch_warnings():
            warnings.simplefilter("default")
            warnings.showwarning = lambda message, *_a, **_k: print(f"dualarm: warning: {message}",
                                                                    file=sys.stderr)
            return args.func(args)
    except DualarmError as exc:
        print(f"dualarm: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:     # Ctrl-C before a command's own handler (say, while a run loads)
        print("\ndualarm: interrupted", file=sys.stderr)
        return 130
    except OSError as exc:
        where = (f"{exc.filename}: " if exc.filename else "")
        hint = "" if exc.filename else " (is the disk full or a file-size limit set?)"
        print(f"dualarm: error: {where}{exc.strerror or exc}{hint}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as exc:
        package = (exc.name or "").split(".")[0]
        if package not in OPTIONAL_PACKAGES:
            raise
        print(f"dualarm: error: this needs {package}, which is not installed: "
              f"pip install {OPTIONAL_PACKAGES[package]}", file=sys.stderr)
        return 2


#: Packages of an optional extra, and how to install them.
OPTIONAL_PACKAGES = {name: "'dualarm[export]'" for name in
                     ("toppra", "rosbags", "onnx", "onnxscript", "onnxruntime")}
OPTIONAL_PACKAGES["ray"] = "'dualarm[ray]'"


if __name__ == "__main__":
    sys.exit(main())
