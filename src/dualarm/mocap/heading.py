"""Detect and correct per-sensor heading offsets from the elbow and wrist kinematic constraints.

Why it is needed. A sensor fused without magnetometer (6D) reports its orientation
in a global frame of its own, which shares the vertical with the others but not
the heading: ``R_G'I = Rz(delta) R_GI``. Calibration in a still pose cannot see
``delta``: it is absorbed into the mounting, and every later rotation of that
sensor is then reported about axes turned by ``delta`` about the vertical
(a flexion read partly as an abduction). No static window can fix this, since a
static pose fixes only R_G'I(0) = Rz(delta) R^0 R_SI, and delta and R_SI trade off.

How it is detected. The elbow and the wrist are 2-DOF joints: the forearm's
rotation relative to the upper arm is ``Ry(q4) Rx(q5)``. A heading offset between
the two sensors breaks that structure as soon as the joint flexes, which shows as
the residual of :func:`dualarm.mocap.joint_angles.two_dof_angles`. The offset of
the forearm relative to the upper arm is the delta that minimises the mean squared
elbow residual (a grid search, then a bounded scalar refinement); the hand's, with
the forearm corrected, the one that minimises the wrist residual (the method of
Laidig et al., 2017, for hinge joints). The upper arm sensor is the heading
reference of its arm: its own offset to the body is not observable from the arm
sensors alone.

An offset is reported as *detected*, and corrected, only when it lowers the RMS
residual by at least ``MIN_IMPROVEMENT`` and is larger than ``MIN_OFFSET``: on a
recording where the joint never flexes, delta is not observable and nothing is
changed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from dualarm.kinematics import ARMS, axis_rotation
from dualarm.mocap.joint_angles import (Calibration, calibrate, segment_rotations_since_zero,
                                        two_dof_angles)
from dualarm.mocap.recording import Recording, sensor_name

#: Smallest reduction of the RMS joint residual (rad) for an offset to count as detected.
MIN_IMPROVEMENT = np.deg2rad(1.0)
#: Smallest offset (rad) worth correcting.
MIN_OFFSET = np.deg2rad(2.0)
#: At most this many evenly spaced samples are used for the estimate.
MAX_SAMPLES = 20_000


@dataclass(frozen=True)
class HeadingEstimate:
    """The heading offset of one sensor relative to its parent segment's sensor.

    Attributes:
        sensor: e.g. ``'right_forearm'``.
        offset_rad: estimated delta (rad) of the sensor's global frame about the vertical.
        rms_before_rad: RMS residual of the joint below the sensor without correction.
        rms_after_rad: RMS residual with ``offset_rad`` removed.
        detected: True when the offset is large and lowers the residual enough; only
            detected offsets are corrected.
    """

    sensor: str
    offset_rad: float
    rms_before_rad: float
    rms_after_rad: float
    detected: bool


def _conjugate_heading(A: np.ndarray, delta: float) -> np.ndarray:
    """Remove a heading offset from base-frame rotations since zero: ``G A G^T``.

    G_z(-delta) in G is a rotation about the base x axis (base x = -z_G), by +delta.
    """
    G = axis_rotation(0, delta)
    return G @ A @ G.T


def _rms_residual(A_parent: np.ndarray, A_child: np.ndarray, delta: float) -> float:
    rel = np.swapaxes(A_parent, -1, -2) @ _conjugate_heading(A_child, delta)
    return float(np.sqrt(np.mean(two_dof_angles(rel)[1] ** 2)))


def _best_offset(A_parent: np.ndarray, A_child: np.ndarray) -> float:
    grid = np.linspace(-np.pi, np.pi, 73)[:-1]
    costs = [_rms_residual(A_parent, A_child, d) for d in grid]
    d0 = grid[int(np.argmin(costs))]
    step = grid[1] - grid[0]
    res = minimize_scalar(lambda d: _rms_residual(A_parent, A_child, d),
                          bounds=(d0 - step, d0 + step), method="bounded",
                          options={"xatol": 1e-7})
    return float((res.x + np.pi) % (2 * np.pi) - np.pi)


def estimate_heading_offsets(rec: Recording, calib: Calibration) -> list[HeadingEstimate]:
    """Estimate the heading offset of each forearm and hand sensor (see module doc).

    Returns:
        Four estimates, left forearm, left hand, right forearm, right hand.
    """
    step = max(1, rec.n_samples // MAX_SAMPLES)
    sub = Recording(rec.time[::step], {s: q[::step] for s, q in rec.quat.items()}, source=rec.source)
    A_all = segment_rotations_since_zero(sub, calib)
    out = []
    for arm in ARMS:
        A = A_all[arm][:, ::step].copy()
        for child in (1, 2):
            parent = child - 1
            delta = _best_offset(A[parent], A[child])
            before = _rms_residual(A[parent], A[child], 0.0)
            after = _rms_residual(A[parent], A[child], delta)
            detected = abs(delta) > MIN_OFFSET and before - after > MIN_IMPROVEMENT
            if detected:  # the next joint down sees the corrected segment
                A[child] = _conjugate_heading(A[child], delta)
            name = sensor_name(arm, ("upper_arm", "forearm", "hand")[child])
            out.append(HeadingEstimate(name, delta if detected else 0.0, before,
                                       after if detected else before, bool(detected)))
    return out


def correct_heading(rec: Recording, estimates: list[HeadingEstimate]) -> Recording:
    """A copy of ``rec`` with each detected offset removed: ``R_GI = Rz(-delta) R_G'I``."""
    quat = dict(rec.quat)
    for e in estimates:
        if e.detected:  # left product with the quaternion of Rz(-delta) = (cos(d/2), 0, 0, -sin(d/2))
            c, s = np.cos(e.offset_rad / 2), -np.sin(e.offset_rad / 2)
            w, x, y, z = np.asarray(quat[e.sensor]).T
            quat[e.sensor] = np.stack([c * w - s * z, c * x - s * y, c * y + s * x, c * z + s * w], axis=1)
    return Recording(rec.time, quat, dict(rec.acc), dict(rec.gyr), rec.source)


def detect_and_correct(rec: Recording, calib_seconds: float,
                       calib_start: float = 0.0) -> tuple[Recording, list[HeadingEstimate]]:
    """Estimate heading offsets and return the corrected recording with the estimates."""
    estimates = estimate_heading_offsets(rec, calibrate(rec, calib_seconds, calib_start))
    return correct_heading(rec, estimates), estimates
