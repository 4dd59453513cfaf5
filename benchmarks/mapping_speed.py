"""Time the IMU -> joint-angle mapping of a one-hour, 100 Hz recording (360,000 samples x 6 sensors).

Usage: python benchmarks/mapping_speed.py [--minutes 60] [--repeat 3] [--csv]
Runs on one core (thread counts pinned to 1 before numpy loads).
"""

import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

import argparse  # noqa: E402
import platform  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from dualarm.mocap.joint_angles import calibrate, joint_angles  # noqa: E402
from dualarm.mocap.mapping import map_recording  # noqa: E402
from dualarm.mocap.retarget import to_baxter  # noqa: E402
from dualarm.mocap.synthetic import example_motion, random_mountings, synthetic_recording  # noqa: E402


def long_recording(minutes: float):
    """The example motion repeated to ``minutes`` at 100 Hz, random mountings, 0.2 deg noise."""
    t, q = example_motion(rate_hz=100.0)
    reps = int(np.ceil(minutes * 60 / t[-1]))
    q = np.tile(q, (reps, 1))[: int(minutes * 6000)]
    rng = np.random.default_rng(0)
    return synthetic_recording(np.arange(len(q)) / 100.0, q, mountings=random_mountings(rng),
                               noise_rad=np.deg2rad(0.2), rng=rng, source="benchmark")


def best_of(repeat: int, fn) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--csv", action="store_true", help="also time writing and reading the CSV file")
    args = ap.parse_args()
    rec = long_recording(args.minutes)
    n = rec.n_samples
    print(f"recording: {n} samples x 6 sensors ({n / 100 / 60:.1f} min at 100 Hz); "
          f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, one thread used")
    rows = [
        ("calibrate + joint angles + retarget (heading off)",
         best_of(args.repeat, lambda: map_recording(rec, heading="off"))),
        ("  of which calibrate", best_of(args.repeat, lambda: calibrate(rec, 1.0))),
        ("  of which joint angles", best_of(args.repeat, lambda: joint_angles(rec, calibrate(rec, 1.0)))),
        ("  of which retarget", best_of(args.repeat, lambda: to_baxter(np.zeros((n, 14))))),
        ("full mapping with heading detection (auto)",
         best_of(args.repeat, lambda: map_recording(rec, heading="auto"))),
    ]
    if args.csv:
        from dualarm.mocap.io import read_recording, write_csv
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "hour.csv"
            rows.append(("write CSV", best_of(1, lambda: write_csv(rec, path))))
            rows.append(("read CSV", best_of(args.repeat, lambda: read_recording(path))))
    print("| step | seconds | samples/s |")
    print("|---|---:|---:|")
    for name, sec in rows:
        print(f"| {name} | {sec:.3f} | {n / sec:,.0f} |")


if __name__ == "__main__":
    main()
