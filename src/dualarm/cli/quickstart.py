"""`dualarm quickstart`: map the built-in example recording, write its tables and figures."""

from __future__ import annotations

import argparse
from pathlib import Path

from dualarm.cli.arguments import OutputDir
from dualarm.cli.mocap import map_file, mapping_summary, write_figures, write_joint_table

EXAMPLE_RECORDING = Path(__file__).resolve().parents[1] / "data" / "example_recording.csv.gz"


def cmd_quickstart(args: argparse.Namespace) -> int:
    """Map the built-in example recording and write tables and figures."""
    out: Path = args.output
    out.mkdir(parents=True, exist_ok=True)
    defaults = argparse.Namespace(calib_seconds=1.0, calib_start=0.0, calib_pose="npose", heading="auto",
                                  sensor_map=None)
    rec, result = map_file(EXAMPLE_RECORDING, defaults)
    write_joint_table(out / "human_joint_angles.csv", result.joints.time, result.joints.q)
    write_joint_table(out / "baxter_joint_angles.csv", result.joints.time, result.robot.q)
    figures = write_figures(out, rec, result, None)
    print(mapping_summary(result, rec))
    print(f"wrote {out / 'human_joint_angles.csv'}, {out / 'baxter_joint_angles.csv'} and "
          f"{len(figures)} figures in {out}/")
    return 0


def add_quickstart_command(sub) -> None:
    """Add ``quickstart`` to the top-level subparsers."""
    quick = sub.add_parser("quickstart", help="map the built-in example recording (tables and figures)",
                           description="Map the built-in example IMU recording to human and Baxter joint "
                                       "angles, and write the tables and figures.")
    quick.add_argument("-o", "--output", type=OutputDir, default=Path("out/quickstart"),
                       help="output directory (default: out/quickstart)")
    quick.set_defaults(func=cmd_quickstart)
