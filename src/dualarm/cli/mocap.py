"""`dualarm mocap joints | plot | example`: IMU recordings -> human joint angles -> Baxter joints."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from dualarm.cli.arguments import InputPath, OutputDir, OutputFile, calibration_arguments


def mapping_summary(result, rec) -> str:
    """A few human-readable lines about a mapping result."""
    from dualarm.task import JOINT_COLUMNS
    from dualarm.mocap.joint_angles import RESIDUAL_COLUMNS

    lines = [f"{rec.source}: {rec.n_samples} samples, {rec.duration:.2f} s at {rec.rate_hz:.1f} Hz; "
             f"calibrated on {result.calibration.window_s[0]:.2f}-{result.calibration.window_s[1]:.2f} s "
             f"(largest sensor turn in the window {np.rad2deg(max(result.calibration.spread.values())):.2f} deg)"]
    for e in result.heading:
        if e.detected:
            joint = "elbow" if e.sensor.endswith("forearm") else "wrist"
            axis = "arm facing" if joint == "elbow" else "forearm twist"
            lines.append(f"{e.sensor}: heading offset {np.rad2deg(e.offset_rad):+.1f} deg, {axis} "
                         f"{np.rad2deg(e.axis_rad):+.1f} deg, corrected ({joint} hinge violation RMS "
                         f"{np.rad2deg(e.rms_before_rad):.1f} -> {np.rad2deg(e.rms_after_rad):.1f} deg)")
    res = np.rad2deg(result.joints.residual)
    lines.append("joint residual (deg, median / 95th pct): " + ", ".join(
        f"{name} {np.median(res[:, i]):.1f}/{np.percentile(res[:, i], 95):.1f}"
        for i, name in enumerate(RESIDUAL_COLUMNS)))
    clipped = result.robot.clipped_fraction
    if clipped.any():
        lines.append("clipped to Baxter's limits: " + ", ".join(
            f"{n} {100 * c:.1f}%" for n, c in zip(JOINT_COLUMNS, clipped) if c > 0))
    else:
        lines.append("clipped to Baxter's limits: none")
    return "\n".join(lines)


def map_file(path: Path, args: argparse.Namespace):
    from dualarm.mocap.io import read_recording
    from dualarm.mocap.mapping import map_recording

    rec = read_recording(path, sensor_map=args.sensor_map)
    return rec, map_recording(rec, calib_seconds=args.calib_seconds, calib_start=args.calib_start,
                              heading=args.heading, calib_pose=args.calib_pose)


def write_joint_table(path: Path, time: np.ndarray, q: np.ndarray) -> None:
    from dualarm.mocap.io import write_table_csv
    from dualarm.mocap.joint_angles import JOINT_COLUMNS

    write_table_csv(path, ["time", *JOINT_COLUMNS], np.column_stack([time, q]))


def cmd_mocap_joints(args: argparse.Namespace) -> int:
    rec, result = map_file(args.input, args)
    q = result.robot.q if args.robot else result.joints.q
    write_joint_table(args.output, result.joints.time, q)
    if args.residuals:
        from dualarm.mocap.io import write_table_csv
        from dualarm.mocap.joint_angles import RESIDUAL_COLUMNS
        write_table_csv(args.residuals, ["time", *RESIDUAL_COLUMNS],
                        np.column_stack([result.joints.time, result.joints.residual]))
    if not args.quiet:
        print(mapping_summary(result, rec), file=sys.stderr)
        print(f"wrote {args.output} ({'Baxter' if args.robot else 'human'} joint angles, rad)", file=sys.stderr)
    return 0


def write_figures(out: Path, rec, result, instants_s: list[float] | None) -> list[Path]:
    from dualarm.kinematics import BAXTER_JOINT_LIMITS
    from dualarm.mocap import plots

    out.mkdir(parents=True, exist_ok=True)
    t = result.joints.time
    if instants_s:
        idx = [int(np.argmin(np.abs(t - (t[0] + s)))) for s in instants_s]
    else:  # the calibration pose and the two samples farthest from it
        start = int(np.searchsorted(t, result.calibration.window_s[0]))
        farthest = start + np.argsort(np.linalg.norm(result.joints.q[start:], axis=1))
        idx = sorted({start, int(farthest[-1]), int(farthest[len(farthest) * 3 // 4])})
    return [
        plots.plot_joint_angles(t - t[0], result.joints.q, out / "human_joint_angles.png",
                                title=f"Human joint angles: {Path(rec.source).name}",
                                residual=result.joints.residual),
        plots.plot_joint_angles(t - t[0], result.robot.q, out / "baxter_joint_angles.png",
                                title=f"Baxter joint vector: {Path(rec.source).name}",
                                limits=BAXTER_JOINT_LIMITS),
        plots.plot_stick_figures(result.joints.q, result.robot.q, idx, out / "stick_figures.png",
                                 time=t - t[0]),
        plots.plot_residuals(t - t[0], result.joints.residual, out / "residuals.png",
                             heading_estimates=result.heading),
    ]


def cmd_mocap_plot(args: argparse.Namespace) -> int:
    rec, result = map_file(args.input, args)
    for path in write_figures(args.output, rec, result, args.instants):
        print(f"wrote {path}", file=sys.stderr)
    return 0


def cmd_mocap_example(args: argparse.Namespace) -> int:
    from dualarm.mocap.io import write_csv
    from dualarm.mocap.synthetic import example_recording

    write_csv(example_recording(), args.output)
    print(f"wrote {args.output}", file=sys.stderr)
    return 0


def _name_map(text: str) -> dict[str, str]:
    pairs = [item.split("=", 1) for item in text.split(",") if item.strip()]
    if not pairs or any(len(p) != 2 or not p[0].strip() or not p[1].strip() for p in pairs):
        raise argparse.ArgumentTypeError(f"expected NAME=SENSOR pairs separated by commas, got {text!r}")
    return {name.strip(): sensor.strip() for name, sensor in pairs}


def _comma_floats(text: str) -> list[float]:
    try:
        return [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated seconds, got {text!r}") from None


def add_mocap_command(sub) -> None:
    """Add the ``mocap`` command group to the top-level subparsers."""
    mocap = sub.add_parser("mocap", help="IMU recordings -> joint angles",
                           description="IMU recordings of both arms -> human joint angles -> Baxter joints.")
    msub = mocap.add_subparsers(dest="mocap_command", required=True, metavar="COMMAND")

    def mapping_options(p: argparse.ArgumentParser) -> None:
        p.add_argument("input", type=InputPath, metavar="INPUT",
                       help="recording: IMU .csv (or .csv.gz), OpenSim .sto or MATLAB .mat; suit .bvh "
                            "or Xsens .mvnx")
        calibration_arguments(p)
        p.add_argument("--sensor-map", type=_name_map, metavar="NAME=SENSOR,...",
                       help="the file's sensor (or column prefix) names for ours, e.g. "
                            "'RUA=right_upper_arm,RFA=right_forearm,...'; for BVH and MVNX the "
                            "segment names, e.g. 'L_UpArm=left_upper_arm,...'")

    joints = msub.add_parser("joints", help="write the 14 joint angles of both arms as CSV",
                             description="Write time,left_q1..left_q7,right_q1..right_q7 (rad), one row "
                                         "per input sample.")
    mapping_options(joints)
    joints.add_argument("-o", "--output", type=OutputFile, required=True, metavar="OUTPUT.csv",
                        help="the joint-angle CSV to write (time and 14 angles, rad; human unless --robot)")
    joints.add_argument("--robot", action="store_true",
                        help="write the retargeted Baxter joint vector (clipped to its limits)")
    joints.add_argument("--residuals", type=OutputFile, metavar="FILE.csv",
                        help="also write the elbow/wrist residual angles (rad)")
    joints.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    joints.set_defaults(func=cmd_mocap_joints)

    plot = msub.add_parser("plot", help="joint-angle curves, residuals and stick figures (PNG)",
                           description="Map a recording and draw its joint angles (degrees), residuals, "
                                       "and the human and Baxter models side by side.")
    mapping_options(plot)
    plot.add_argument("-o", "--output", type=OutputDir, required=True, metavar="DIR",
                      help="folder for the figures")
    plot.add_argument("--instants", type=_comma_floats, metavar="T1,T2,...",
                      help="seconds from the start at which to draw stick figures")
    plot.set_defaults(func=cmd_mocap_plot)

    example = msub.add_parser("example", help="write the built-in example recording",
                              description="Regenerate the built-in example recording (deterministic).")
    example.add_argument("-o", "--output", type=OutputFile, required=True, metavar="FILE.csv",
                         help="the example recording to write")
    example.set_defaults(func=cmd_mocap_example)
