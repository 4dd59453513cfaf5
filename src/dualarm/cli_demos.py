"""`dualarm demos ...` and `dualarm constraints ...`: demonstration sets, constraint extraction, plots, analysis."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from dualarm.cli_types import InputPath, OutputDir, OutputFile
from dualarm.demos.formats import LABELS_NAME
from dualarm.cli_types import non_negative as _non_negative
from dualarm.cli_types import positive_int as _positive_int
from dualarm.errors import InputError


def _percentile(text: str) -> float:
    value = _non_negative(text)
    if value >= 50:
        raise argparse.ArgumentTypeError(f"must be in [0, 50), got {text!r}")
    return value


def _demo_dir(args: argparse.Namespace) -> Path:
    from dualarm.demos.formats import DEFAULT_DEMO_DIR

    return Path(args.demo_dir) if args.demo_dir is not None else DEFAULT_DEMO_DIR


def _options(args: argparse.Namespace):
    from dualarm.demos.loading import MappingOptions

    return MappingOptions(calib_seconds=args.calib_seconds, calib_start=args.calib_start, heading=args.heading,
                          lowpass_hz=args.lowpass_hz)


def _auto_windows(demos, args) -> dict[str, np.ndarray]:
    from dualarm.demos.segmentation import segment_demo

    calib_end = args.calib_start + args.calib_seconds
    return {d.name: segment_demo(d.time, d.q, None if args.no_grip else d.grip, calib_end_s=calib_end,
                                 demo=d.name) for d in demos}


def _check_output(path: Path, suffixes: tuple[str, ...]) -> None:
    if not path.name.lower().endswith(suffixes):
        raise InputError(f"output must end in {' or '.join(suffixes)}", source=str(path))


# --------------------------------------------------------------------------- demos

def cmd_demos_generate(args: argparse.Namespace) -> int:
    """Generate a demonstration set (IMU CSVs and labels) from the scripted expert."""
    from dualarm.demos.generate import generate_demos, write_demo_set

    out = Path(args.output)
    demos = generate_demos(args.count, args.seed, progress=not args.quiet)
    paths = write_demo_set(demos, out)
    if not args.quiet:
        for d in demos:
            print(f"{d.name}: env seed {d.env_seed}, {d.time[-1]:.2f} s, {len(d.time)} samples", file=sys.stderr)
        print(f"wrote {len(paths) - 1} recordings and {paths[-1].name} in {out}/", file=sys.stderr)
    return 0


def cmd_demos_segment(args: argparse.Namespace) -> int:
    """Segment demonstrations automatically; compare with labels when there are any."""
    from dualarm.demos.labels import read_labels, write_labels
    from dualarm.demos.loading import load_demo_dir
    from dualarm.demos.segmentation import segmentation_agreement

    if args.output:
        _check_output(args.output, (".csv",))
    demo_dir = _demo_dir(args)
    demos, _ = load_demo_dir(demo_dir, options=_options(args), require_labels=False, with_grip=True)
    auto = _auto_windows(demos, args)
    labels_path = Path(args.labels) if args.labels else demo_dir / LABELS_NAME
    if args.labels or labels_path.exists():
        labels = read_labels(labels_path)
        errors, agree = [], []
        print("demo      boundary |auto - label| [s] per arm: reach start, grasp start, align start, "
              "align end   frames agreeing")
        for d in demos:
            if d.name not in labels:
                continue
            r = segmentation_agreement(d.time, auto[d.name], labels[d.name].windows)
            errors.append(r["boundary_error_s"])
            agree.append(r["frame_agreement"])
            e = r["boundary_error_s"]
            print(f"{d.name:<9} left {' '.join(f'{x:.3f}' for x in e[0])}  right "
                  f"{' '.join(f'{x:.3f}' for x in e[1])}   {100 * r['frame_agreement'].mean():.1f}%")
        if errors:
            e = np.stack(errors)
            print(f"mean      {' '.join(f'{x:.3f}' for x in e.mean(axis=(0, 1)))} (both arms)   "
                  f"{100 * np.mean(agree):.1f}%")
            print(f"max       {' '.join(f'{x:.3f}' for x in e.max(axis=(0, 1)))}")
    if args.output:
        write_labels(args.output, auto)
        print(f"wrote {args.output}", file=sys.stderr)
    return 0


# --------------------------------------------------------------------------- constraints

def cmd_constraints_extract(args: argparse.Namespace) -> int:
    """Eq. 12 over a folder of demonstrations -> constraints YAML."""
    from dualarm.constraints.extraction import extract_constraints, extraction_provenance
    from dualarm.demos.loading import load_demo_dir
    from dualarm.constraints.constraint_set import parse_segments

    _check_output(args.output, (".yaml", ".yml"))
    groups = parse_segments(args.segments)
    spec = ",".join("+".join(g) for g in groups)
    demo_dir = _demo_dir(args)
    options = _options(args)
    demos, labels = load_demo_dir(demo_dir, args.labels, options, require_labels=not args.auto_segment,
                                  with_grip=args.auto_segment, progress=not args.quiet)
    if args.auto_segment:
        windows = _auto_windows(demos, args)
        labels_file, origin = None, "automatic segmentation (dualarm.demos.segmentation.segment_demo)"
    else:
        windows = {name: lab.windows for name, lab in labels.items()}
        labels_file = Path(args.labels) if args.labels else demo_dir / LABELS_NAME
        origin = "labels file"
    provenance = extraction_provenance(demos, labels_file, origin, options, spec, args.percentile, args.margin)
    cs = extract_constraints(demos, windows, groups, percentile=args.percentile, margin=args.margin,
                             name=args.name, provenance=provenance)
    cs.save(args.output)
    if not args.quiet:
        print(_describe(cs), file=sys.stderr)
        print(f"wrote {args.output}", file=sys.stderr)
    return 0


def _describe(cs) -> str:
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

    _check_output(args.output, (".png", ".pdf", ".svg"))
    cs = ConstraintSet.load(args.constraints)
    demos, labels = load_demo_dir(_demo_dir(args), args.labels, _options(args))
    path = plot_constraints(cs, demos, labels, args.output)
    print(f"wrote {path}", file=sys.stderr)
    return 0


def cmd_constraints_analyze(args: argparse.Namespace) -> int:
    """Volume fractions and the expert's share of steps inside, for one or more constraint files."""
    from dualarm.constraints.analysis import arm_volume_fractions, expert_inside_fractions, expert_rollouts
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


# --------------------------------------------------------------------------- parser

def add_demo_commands(sub) -> None:
    """Add the ``demos`` and ``constraints`` command groups to the top-level subparsers."""
    from dualarm.demos.loading import DEFAULT_LOWPASS_HZ

    def demo_dir_argument(p: argparse.ArgumentParser, flag: bool = False) -> None:
        help_ = "folder of IMU recordings (.csv, .csv.gz, .sto, .mat); default: the shipped set of 10"
        if flag:
            p.add_argument("--demos", dest="demo_dir", type=InputPath, metavar="DIR", help=help_)
        else:
            p.add_argument("demo_dir", type=InputPath, nargs="?", metavar="DEMO_DIR", help=help_)

    def mapping_options(p: argparse.ArgumentParser) -> None:
        p.add_argument("--calib-seconds", type=_non_negative, default=1.0, metavar="S",
                       help="zero-pose calibration window, s (default: 1.0)")
        p.add_argument("--calib-start", type=_non_negative, default=0.0, metavar="S",
                       help="start of the calibration window, s after the first sample (default: 0)")
        p.add_argument("--heading", choices=("auto", "off"), default="auto",
                       help="heading-offset correction of the mapping (default: auto)")
        p.add_argument("--lowpass-hz", type=_non_negative, default=DEFAULT_LOWPASS_HZ, metavar="HZ",
                       help=f"zero-phase low-pass cut-off on the joint angles, 0 for none "
                            f"(default: {DEFAULT_LOWPASS_HZ:g})")

    def labels_option(p: argparse.ArgumentParser) -> None:
        p.add_argument("--labels", type=InputPath, metavar="FILE.csv",
                       help=f"labels file (demo,arm,subtask,start_s,end_s); default: DEMO_DIR/{LABELS_NAME}")

    demos = sub.add_parser("demos", help="demonstration sets: generate, segment",
                           description="Demonstration sets of the reach-grasp-align task.")
    dsub = demos.add_subparsers(dest="demos_command", required=True, metavar="COMMAND")
    gen = dsub.add_parser("generate", help="make IMU demonstrations from the scripted expert",
                          description="Run the scripted expert at seeded placements, add human variability "
                                      "(speed, timing, elbow swivel, tremor) and write six-sensor IMU "
                                      "recordings (random mountings, noise, a zero-pose window) with "
                                      "sub-task labels. The same --count and --seed give the same bytes; "
                                      "--count 10 --seed 0 is the shipped set.")
    gen.add_argument("-o", "--output", type=OutputDir, required=True, metavar="DIR")
    gen.add_argument("--count", type=_positive_int, default=10, help="number of demonstrations (default: 10)")
    gen.add_argument("--seed", type=int, default=0, help="seed (default: 0)")
    gen.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    gen.set_defaults(func=cmd_demos_generate)

    seg = dsub.add_parser("segment", help="automatic sub-task segmentation (and agreement with labels)",
                          description="Find each arm's reach, grasp and align from the hand's motion "
                                      "(Baxter forward kinematics) and the gripper events when the recording "
                                      f"has left_grip/right_grip columns. With labels (DEMO_DIR/{LABELS_NAME} or "
                                      "--labels), print how well they agree.")
    demo_dir_argument(seg)
    labels_option(seg)
    mapping_options(seg)
    seg.add_argument("--no-grip", action="store_true", help="ignore gripper-event columns")
    seg.add_argument("-o", "--output", type=OutputFile, metavar="FILE.csv", help="write the automatic labels")
    seg.set_defaults(func=cmd_demos_segment)

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
    ext.add_argument("--margin", type=_non_negative, default=0.0, metavar="RAD",
                     help="widen every bound by this much, rad (default: 0)")
    ext.add_argument("--percentile", type=_percentile, default=0.0, metavar="P",
                     help="per-demo P-th and (100-P)-th percentiles instead of min and max (default: 0)")
    ext.add_argument("--name", default=None, help="name of the set (default: single or multi)")
    mapping_options(ext)
    ext.add_argument("-o", "--output", type=OutputFile, required=True, metavar="FILE.yaml")
    ext.add_argument("-q", "--quiet", action="store_true")
    ext.set_defaults(func=cmd_constraints_extract)

    plot = csub.add_parser("plot", help="demonstrations' joint curves with the constraint bands (PNG)",
                           description="Every demonstration's joint angles per arm against task phase, "
                                       "with each segment's band.")
    plot.add_argument("constraints", type=InputPath, metavar="FILE.yaml")
    demo_dir_argument(plot, flag=True)
    labels_option(plot)
    mapping_options(plot)
    plot.add_argument("-o", "--output", type=OutputFile, required=True, metavar="FIG.png")
    plot.set_defaults(func=cmd_constraints_plot)

    ana = csub.add_parser("analyze", help="joint-space share and the expert's steps inside",
                          description="For each constraints file: the share of Baxter's joint range "
                                      "(per joint and as a volume) each segment leaves, and the share of the "
                                      "scripted expert's steps inside the range of its arm's segment.")
    ana.add_argument("constraints", type=InputPath, nargs="+", metavar="FILE.yaml")
    ana.add_argument("--episodes", type=_positive_int, default=100, help="expert episodes (default: 100)")
    ana.add_argument("--seed", type=int, default=1000, help="seed of the first episode (default: 1000)")
    ana.add_argument("-o", "--output", type=OutputDir, metavar="DIR",
                     help="write constraints_volume_fractions.png and constraints_expert_inside.png here")
    ana.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    ana.set_defaults(func=cmd_constraints_analyze)
