"""`dualarm constraints extract | plot | analyze`: joint-angle constraints from demonstrations
(paper Eqs. 11-12), their bands over the demonstrations, and their analysis."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from dualarm.cli.arguments import (InputPath, OutputDir, OutputFile, non_negative, positive_int,
                                   seed_number)
from dualarm.cli.demos import (check_suffix, demo_dir_argument, demo_dir_of, labels_option,
                               mapping_options, mapping_options_of)
from dualarm.errors import InputError


def _percentile(text: str) -> float:
    value = non_negative(text)
    if value >= 50:
        raise argparse.ArgumentTypeError(f"must be in [0, 50), got {text!r}")
    return value


def cmd_constraints_extract(args: argparse.Namespace) -> int:
    """Eq. 12 over a folder of demonstrations -> constraints YAML."""
    from dualarm.constraints.extraction import constraints_from_folder

    check_suffix(args.output, (".yaml", ".yml"))
    cs = constraints_from_folder(args.demo_dir, args.segments, name=args.name, labels_path=args.labels,
                                 options=mapping_options_of(args), percentile=args.percentile,
                                 margin=args.margin, auto_segment=args.auto_segment,
                                 use_grip=not args.no_grip, progress=not args.quiet)
    cs.save(args.output)
    if not args.quiet:
        print(describe(cs), file=sys.stderr)
        print(f"wrote {args.output}", file=sys.stderr)
    return 0


def describe(cs) -> str:
    """Bounds in degrees and volume fractions, one line per joint and segment."""
    from dualarm.constraints.analysis import arm_volume_fractions
    from dualarm.task import JOINT_COLUMNS

    vol = arm_volume_fractions(cs)
    lines = [f"constraint set '{cs.name}': {len(cs.segments)} segment(s)"]
    for s, seg in enumerate(cs.segments):
        lines.append(f"  segment {s + 1} ({'+'.join(seg.subtasks)}): volume fraction left arm {vol[s, 0]:.2e}, "
                     f"right arm {vol[s, 1]:.2e}, both {cs.volume_fraction()[s]:.2e}")
        lines.append("    " + ", ".join(f"{c} [{np.rad2deg(lo):.1f}, {np.rad2deg(hi):.1f}]"
                                        for c, lo, hi in zip(JOINT_COLUMNS, seg.lower, seg.upper)) + " deg")
    return "\n".join(lines)


def cmd_constraints_plot(args: argparse.Namespace) -> int:
    """Demonstrations' joint curves with the constraint bands."""
    from dualarm.demos.loading import load_demo_dir
    from dualarm.constraints.plots import plot_constraints
    from dualarm.constraints.constraint_set import ConstraintSet

    check_suffix(args.output, (".png", ".pdf", ".svg"))
    cs = ConstraintSet.load(args.constraints)
    demos, labels = load_demo_dir(demo_dir_of(args), args.labels, mapping_options_of(args))
    path = plot_constraints(cs, demos, labels, args.output)
    print(f"wrote {path}", file=sys.stderr)
    return 0


def cmd_constraints_analyze(args: argparse.Namespace) -> int:
    """Volume fractions and the expert's share of steps inside, for one or more constraint files."""
    from dualarm.constraints.analysis import arm_volume_fractions, expert_inside_fractions
    from dualarm.envs.rollout import expert_rollouts
    from dualarm.constraints.constraint_set import ConstraintSet
    from dualarm.task import JOINT_COLUMNS

    sets = {}
    for path in args.constraints:
        label = Path(path).stem
        if label in sets:
            raise InputError(f"two files named {label!r}; rename one", source=str(path))
        sets[label] = ConstraintSet.load(path)
    q, sub, success = expert_rollouts(args.episodes, args.seed, progress=not args.quiet)
    reports = {label: expert_inside_fractions(cs, q, sub) for label, cs in sets.items()}
    fractions = {label: (cs, reports[label].fraction) for label, cs in sets.items()}
    print(f"scripted expert: {args.episodes} episodes (seeds {args.seed}..{args.seed + args.episodes - 1}), "
          f"{len(q)} steps, success rate {success:.3f}")
    header = "joint".ljust(10) + "".join(f"{c:>10}" for c in JOINT_COLUMNS)
    for label, cs in sets.items():
        vol, width, report = arm_volume_fractions(cs), cs.width_fractions(), reports[label]
        for s, seg in enumerate(cs.segments):
            print(f"\n{label}: segment {s + 1} ({'+'.join(seg.subtasks)}): volume fraction of the joint box: "
                  f"left arm {vol[s, 0]:.2e}, right arm {vol[s, 1]:.2e}, both arms {cs.volume_fraction()[s]:.2e}")
            print(header)
            print("width %".ljust(10) + "".join(f"{100 * w:>10.1f}" for w in width[s]))
            print("inside %".ljust(10) + "".join(f"{100 * f:>10.1f}" for f in report.fraction[s]))
            print(f"expert steps in this segment: left {report.count[s, 0]}, right {report.count[s, 1]}; "
                  f"with all 7 joints inside: left {100 * report.all_joints[s, 0]:.1f}%, "
                  f"right {100 * report.all_joints[s, 1]:.1f}%")
    if args.output is not None:
        from dualarm.constraints.plots import plot_expert_inside, plot_volume_fractions

        paths = [plot_volume_fractions(sets, args.output / "constraints_volume_fractions.png"),
                 plot_expert_inside(fractions, args.output / "constraints_expert_inside.png",
                                    subtitle=f"{args.episodes} episodes")]
        for p in paths:
            print(f"wrote {p}", file=sys.stderr)
    return 0


def add_constraints_command(sub) -> None:
    """Add the ``constraints`` command group to the top-level subparsers."""
    cons = sub.add_parser("constraints", help="joint-angle constraints: extract, plot, analyze",
                          description="Joint-angle constraints from demonstrations (paper Eqs. 11-12).")
    csub = cons.add_subparsers(dest="constraints_command", required=True, metavar="COMMAND")
    ext = csub.add_parser("extract", help="demonstrations -> constraints file (Eq. 12)",
                          description="Map each recording to Baxter joint angles, split it by sub-task, and "
                                      "take per segment and joint the minimum of the per-demo minima and the "
                                      "maximum of the per-demo maxima (Eq. 12).")
    demo_dir_argument(ext)
    labels_option(ext)
    ext.add_argument("--auto-segment", action="store_true",
                     help="use automatic segmentation instead of a labels file")
    ext.add_argument("--no-grip", action="store_true", help="with --auto-segment: ignore gripper events")
    ext.add_argument("--segments", default="reach+grasp,align", metavar="SPEC",
                     help="sub-tasks per segment: 'reach+grasp+align' is C1 (single), 'reach+grasp,align' "
                          "C2 and C3 (multi; default)")
    ext.add_argument("--margin", type=non_negative, default=0.0, metavar="RAD",
                     help="widen every bound by this much, rad (default: 0)")
    ext.add_argument("--percentile", type=_percentile, default=0.0, metavar="P",
                     help="per-demo P-th and (100-P)-th percentiles instead of min and max (default: 0)")
    ext.add_argument("--name", default=None, help="name of the set (default: single or multi)")
    mapping_options(ext)
    ext.add_argument("-o", "--output", type=OutputFile, required=True, metavar="FILE.yaml",
                     help="the constraints file to write")
    ext.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    ext.set_defaults(func=cmd_constraints_extract)

    plot = csub.add_parser("plot", help="demonstrations' joint curves with the constraint bands (PNG)",
                           description="Every demonstration's joint angles per arm against task phase, "
                                       "with each segment's band.")
    plot.add_argument("constraints", type=InputPath, metavar="FILE.yaml",
                      help="a constraints file (`dualarm constraints extract`)")
    demo_dir_argument(plot, flag=True)
    labels_option(plot)
    mapping_options(plot)
    plot.add_argument("-o", "--output", type=OutputFile, required=True, metavar="FIG.png",
                      help="the figure to write")
    plot.set_defaults(func=cmd_constraints_plot)

    ana = csub.add_parser("analyze", help="joint-space share and the expert's steps inside",
                          description="For each constraints file: the share of Baxter's joint range "
                                      "(per joint and as a volume) each segment leaves, and the share of the "
                                      "scripted expert's steps inside the range of its arm's segment.")
    ana.add_argument("constraints", type=InputPath, nargs="+", metavar="FILE.yaml",
                     help="one or more constraints files, compared side by side")
    ana.add_argument("--episodes", type=positive_int, default=100, help="expert episodes (default: 100)")
    ana.add_argument("--seed", type=seed_number, default=1000, help="seed of the first episode (default: 1000)")
    ana.add_argument("-o", "--output", type=OutputDir, metavar="DIR",
                     help="write constraints_volume_fractions.png and constraints_expert_inside.png here")
    ana.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    ana.set_defaults(func=cmd_constraints_analyze)
