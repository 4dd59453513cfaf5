"""Compare IMU fusion methods (vqf, ahrs Madgwick/Mahony, imufusion) on a real recording.

For the six arm sensors of the qmt full-body example recording, each method turns raw
acc + gyr into orientations, compared with the recording's own ``quat``. That ``quat``
is not of the frame acc/gyr are measured in: per sensor, its body frame B differs from
the IMU frame S by a constant rotation C (about 110-130 deg). C is fitted once per sensor
from the gyroscope against the reference's own angular velocity (omega_B = C omega_S),
independently of any fusion method, and each estimate is mapped to B (R_B = R_S C^T):

- inclination error: angle between the global vertical seen from the sensor,
  R^T [0, 0, 1], of estimate and reference (heading-independent), first 5 s skipped;
- heading drift: change, from the first window (5-10 s) to the last 5 s, of the heading
  of R_ref R_est^T (constant if the two differ only by their arbitrary heading);
- throughput: samples per second of wall time, one sensor at a time.

Usage: python benchmarks/fusion_compare.py [--mat PATH] [--no-align]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import scipy.io
from scipy.spatial.transform import Rotation

from dualarm.mocap.fusion import METHODS, orientation_from_imu

ARM_SENSORS = ("upper_arm_left", "forearm_left", "hand_left",
               "upper_arm_right", "forearm_right", "hand_right")
DEFAULT_MAT = (Path(__file__).resolve().parents[2]
               / "shared/data/real-imu/qmt_full_body_example_data.mat")
RATE_HZ = 100.0
SKIP_S = 5.0
EZ = np.array([0.0, 0.0, 1.0])


def rot(q: np.ndarray) -> Rotation:
    return Rotation.from_quat(q, scalar_first=True)


def inclination_error_deg(r_est: Rotation, q_ref: np.ndarray) -> np.ndarray:
    up_est = r_est.inv().apply(EZ)
    up_ref = rot(q_ref).inv().apply(EZ)
    return np.degrees(np.arccos(np.clip(np.sum(up_est * up_ref, axis=1), -1.0, 1.0)))


def heading_deg(r: Rotation) -> np.ndarray:
    """Heading (about global z) of a global-frame rotation, from where it sends e_x."""
    x = r.apply([1.0, 0.0, 0.0])
    return np.degrees(np.arctan2(x[:, 1], x[:, 0]))


def circ_mean_deg(a: np.ndarray) -> float:
    a = np.radians(a)
    return float(np.degrees(np.arctan2(np.sin(a).mean(), np.cos(a).mean())))


def wrap_deg(a: float) -> float:
    return (a + 180.0) % 360.0 - 180.0


def heading_drift_deg(r_est: Rotation, q_ref: np.ndarray) -> float:
    delta = heading_deg(rot(q_ref) * r_est.inv())
    n5 = int(SKIP_S * RATE_HZ)
    return wrap_deg(circ_mean_deg(delta[-n5:]) - circ_mean_deg(delta[n5:2 * n5]))


def frame_alignment(gyr: np.ndarray, q_ref: np.ndarray) -> Rotation:
    """Constant C with omega_ref ~ C gyr (omega_ref: body-frame rate of the reference)."""
    r = rot(q_ref)
    omega_ref = (r[:-1].inv() * r[1:]).as_rotvec() * RATE_HZ
    c, _ = Rotation.align_vectors(omega_ref, 0.5 * (gyr[:-1] + gyr[1:]))
    return c


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mat", type=Path, default=DEFAULT_MAT,
                        help="qmt_full_body_example_data.mat (default: %(default)s)")
    parser.add_argument("--no-align", action="store_true",
                        help="compare raw estimates with quat, without the frame alignment C")
    args = parser.parse_args(argv)
    data = scipy.io.loadmat(args.mat, squeeze_me=True, struct_as_record=False)

    skip = int(SKIP_S * RATE_HZ)
    align = {n: frame_alignment(np.asarray(data[n].gyr, float), data[n].quat) for n in ARM_SENSORS}
    rows = []
    for method in METHODS:
        errors, drifts, n_samples, seconds = [], [], 0, 0.0
        for name in ARM_SENSORS:
            s = data[name]
            acc, gyr = np.asarray(s.acc, float), np.asarray(s.gyr, float)
            t0 = time.perf_counter()
            q = orientation_from_imu(acc, gyr, RATE_HZ, method=method)
            seconds += time.perf_counter() - t0
            n_samples += len(q)
            r_b = rot(q) if args.no_align else rot(q) * align[name].inv()  # in frame B
            errors.append(inclination_error_deg(r_b[skip:], s.quat[skip:]))
            drifts.append(heading_drift_deg(r_b, s.quat))
        err = np.concatenate(errors)
        drift = np.abs(drifts)
        rows.append((method, np.median(err), np.percentile(err, 95),
                     np.median(drift), drift.max(), n_samples / seconds))

    print(f"Recording: {args.mat.name}, {len(data['t'])} samples at {RATE_HZ:g} Hz, "
          f"sensors: {', '.join(ARM_SENSORS)}; first {SKIP_S:g} s skipped.\n")
    print("| method | inclination error median (deg) | inclination error p95 (deg) "
          "| heading drift vs reference, median abs (deg) | heading drift, max abs (deg) "
          "| throughput (samples/s) |")
    print("|---|---:|---:|---:|---:|---:|")
    for m, med, p95, dmed, dmax, thr in rows:
        print(f"| {m} | {med:.2f} | {p95:.2f} | {dmed:.1f} | {dmax:.1f} | {thr:,.0f} |")

    print("\nFitted frame alignment C (IMU frame -> reference body frame), rotation angle: "
          + ", ".join(f"{n} {np.degrees(align[n].magnitude()):.1f} deg" for n in ARM_SENSORS)
          + (" (not applied: --no-align)" if args.no_align else ""))


if __name__ == "__main__":
    main()
