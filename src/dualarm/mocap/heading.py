"""Detect and correct heading offsets from the elbow and wrist hinge constraints.

Why it is needed. A sensor fused without magnetometer (6D) reports its orientation
in a global frame of its own, which shares the vertical with the others but not
the heading: ``R_G'I = Rz(delta) R_GI``. Two things follow, and no static pose can
reveal either (in a still pose delta trades off against the unknown mounting):

* *relative heading*: the forearm (or hand) sensor's heading differs from the
  upper arm's by ``delta``, so its later rotations are reported about axes turned
  by delta about the vertical;
* *facing*: the person does not face +x in the upper arm sensor's global frame,
  but some heading ``phi``: flexion is then read partly as abduction. For the
  arm's three sensors together this is a common heading offset.

How it is detected. The elbow and the wrist are hinges for the purpose of this
model (``Ry(flexion) Rx(roll)``): the child's long axis stays perpendicular to a
flexion axis fixed in the parent. Written in the parent segment's frame, the
flexion axis is ``n = (0, cos phi, -sin phi)`` (phi = 0: the model's y axis), and
the violation at time t is ``n . v_t``, with ``v_t`` the child's long axis. For a
given relative heading delta the best phi has a closed form (the eigenvector of
the smallest eigenvalue of the 2x2 scatter of (v_y, v_z)); delta is found by a
grid search and a bounded refinement of that smallest eigenvalue (after the
hinge-joint method of Laidig et al., 2017). Of the two opposite axes the one that
makes elbow flexion positive is kept; for the wrist, the one within 90 degrees of
the model's.

* Elbow: delta is the forearm sensor's heading relative to the upper arm's, phi
  the arm's facing; phi is applied to all three sensors of the arm.
* Wrist: delta is the hand sensor's heading relative to the (corrected) forearm;
  phi is where the wrist's flexion axis lay around the forearm in the calibration
  pose: 0 with the palms forward (the model's q = 0), about +-90 degrees with the
  palms towards the thighs. It is applied as a *twist* of the forearm and hand
  mountings about their long axes (:func:`twist_mountings`), so the calibration
  pose then reads q5 = -phi (forearm roll) instead of 0, and wrist flexion is read
  as q6 instead of being left in the residual.

A correction is *detected*, and applied, only when it lowers the RMS violation by
``MIN_IMPROVEMENT`` and turns something by more than ``MIN_OFFSET``: on a
recording where the joint never flexes, nothing is observable and nothing changes.
The upper arm sensor stays the heading reference of its arm.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.spatial.transform import Rotation

from dualarm.kinematics import ARMS, axis_rotation, packed, wrap_angle
from dualarm.mocap.joint_angles import Calibration, calibrate, segment_rotations_since_zero
from dualarm.mocap.recording import Recording, sensor_name

#: Smallest reduction of the RMS hinge violation (rad) for a correction to count as detected.
MIN_IMPROVEMENT = np.deg2rad(1.0)
#: Smallest heading or facing change (rad) worth applying.
MIN_OFFSET = np.deg2rad(2.0)
#: Mean elbow flexion (rad) above which its sign can tell the two opposite axes apart.
MIN_MEAN_FLEXION = np.deg2rad(5.0)
#: At most this many evenly spaced samples are used for the estimate.
MAX_SAMPLES = 10_000


@dataclass(frozen=True)
class HeadingEstimate:
    """The hinge fit of one joint (elbow or wrist) of one arm.

    Attributes:
        sensor: the child sensor whose heading is estimated, e.g. ``'right_forearm'``.
        offset_rad: its heading offset delta (rad) about the vertical, relative to the parent.
        axis_rad: phi (rad): where the flexion axis lies about the parent's long axis.
            For the elbow it is the arm's facing offset, applied to all its sensors.
        rms_before_rad: RMS hinge violation (rad) with no correction.
        rms_after_rad: RMS hinge violation with the correction.
        detected: True when the correction is applied.
    """

    sensor: str
    offset_rad: float
    axis_rad: float
    rms_before_rad: float
    rms_after_rad: float
    detected: bool


def _conjugate_heading(A: np.ndarray, delta: float) -> np.ndarray:
    """Remove a heading offset ``delta`` from base-frame rotations since zero: ``G A G^T``.

    ``Rz(-delta)`` in G is, in the base frame (base x = -z_G), ``Rx(+delta)``.
    """
    G = axis_rotation(0, delta)
    return G @ A @ G.T


def _child_axis(A_parent: np.ndarray, A_child: np.ndarray, delta: float) -> np.ndarray:
    """(T, 3) child's long axis in the parent frame, child heading ``delta`` removed.

    ``A_p^T (G A_c G^T) e_x = A_p^T G (A_c e_x)`` since G turns about x: vectors only.
    """
    return np.einsum("tji,tj->ti", A_parent, A_child[:, :, 0] @ axis_rotation(0, delta).T)


def _hinge_fit(A_parent: np.ndarray, A_child: np.ndarray, delta: float) -> tuple[float, float]:
    """Best flexion-axis angle phi and its mean squared violation for a child heading ``delta``."""
    child_axis = _child_axis(A_parent, A_child, delta)
    vy, vz = child_axis[:, 1], child_axis[:, 2]
    scatter = np.array([[vy @ vy, -vy @ vz], [-vy @ vz, vz @ vz]]) / len(vy)
    values, vectors = np.linalg.eigh(scatter)  # n = (cos phi, sin phi) in the (vy, -vz) plane
    cos_phi, sin_phi = vectors[:, 0]
    return float(np.arctan2(sin_phi, cos_phi)), float(max(values[0], 0.0))


def _violation(A_parent: np.ndarray, A_child: np.ndarray, delta: float, phi: float) -> float:
    child_axis = _child_axis(A_parent, A_child, delta)
    along_axis = np.cos(phi) * child_axis[:, 1] - np.sin(phi) * child_axis[:, 2]
    return float(np.sqrt(np.mean(np.arcsin(np.clip(along_axis, -1, 1)) ** 2)))


def _best_heading(A_parent: np.ndarray, A_child: np.ndarray) -> float:
    grid = np.linspace(-np.pi, np.pi, 73)[:-1]
    costs = [_hinge_fit(A_parent, A_child, d)[1] for d in grid]
    d0 = grid[int(np.argmin(costs))]
    step = grid[1] - grid[0]
    res = minimize_scalar(lambda d: _hinge_fit(A_parent, A_child, d)[1],
                          bounds=(d0 - step, d0 + step), method="bounded", options={"xatol": 1e-9})
    return float(wrap_angle(res.x))


def _fit_joint(A_parent, A_child, *, positive_flexion: bool) -> tuple[float, float, float, float, bool]:
    """(delta, phi, rms before, rms after, detected) of one hinge."""
    delta = _best_heading(A_parent, A_child)
    phi, _ = _hinge_fit(A_parent, A_child, delta)
    flexed = False
    if positive_flexion:
        # Flexion a = atan2(-z, x) of the child axis in the corrected parent frame: keep a > 0 on average.
        axis = _child_axis(A_parent, A_child, delta) @ axis_rotation(0, phi).T
        # (-axis[:, 2] is already a fresh contiguous array; the column needs packing)
        mean_flexion = float(np.mean(np.arctan2(-axis[:, 2], packed(axis[:, 0]))))
        flexed = abs(mean_flexion) > MIN_MEAN_FLEXION
        if mean_flexion < 0:
            phi += np.pi
    elif abs(wrap_angle(phi)) > np.pi / 2:
        phi += np.pi
    phi = float(wrap_angle(phi))
    before = _violation(A_parent, A_child, 0.0, 0.0)
    after = _violation(A_parent, A_child, delta, phi)
    turned = max(abs(delta), abs(phi))
    detected = turned > MIN_OFFSET and before - after > MIN_IMPROVEMENT
    if flexed and abs(phi) > np.pi / 2:  # elbow read backwards (flexion < 0): always worth fixing
        detected = True
    return delta, phi, before, after, bool(detected)


def estimate_heading_offsets(rec: Recording, calib: Calibration) -> list[HeadingEstimate]:
    """Hinge fits of the elbow and the wrist of both arms (see the module docstring).

    Returns:
        Four estimates: left elbow (sensor left_forearm), left wrist (left_hand),
        right elbow, right wrist.
    """
    step = max(1, rec.n_samples // MAX_SAMPLES)
    sub = Recording(rec.time[::step], {s: q[::step] for s, q in rec.quat.items()}, source=rec.source)
    A_all = segment_rotations_since_zero(sub, calib)
    out = []
    for arm in ARMS:
        A = A_all[arm].copy()
        # Elbow: forearm heading, then the arm's facing (all three segments).
        delta, phi, before, after, detected = _fit_joint(A[0], A[1], positive_flexion=True)
        if detected:
            A[1] = _conjugate_heading(A[1], delta)
            A = _conjugate_heading(A, phi)
        out.append(HeadingEstimate(sensor_name(arm, "forearm"), delta if detected else 0.0,
                                   phi if detected else 0.0, before, after if detected else before, detected))
        # Wrist: hand heading relative to the corrected forearm, and the forearm's twist.
        delta, phi, before, after, detected = _fit_joint(A[1], A[2], positive_flexion=False)
        out.append(HeadingEstimate(sensor_name(arm, "hand"), delta if detected else 0.0,
                                   phi if detected else 0.0, before, after if detected else before, detected))
    return out


def _turn_about_vertical(quat: np.ndarray, angle: float) -> np.ndarray:
    """(T, 4) quaternions (w, x, y, z) left-multiplied by Rz(angle)."""
    c, s = np.cos(angle / 2), np.sin(angle / 2)
    w, x, y, z = np.asarray(quat).T
    return np.stack([c * w - s * z, c * x - s * y, c * y + s * x, c * z + s * w], axis=1)


def correct_heading(rec: Recording, estimates: list[HeadingEstimate]) -> Recording:
    """A copy of ``rec`` with detected offsets removed: ``R_GI = Rz(-delta) R_G'I``,
    and each arm's facing ``Rz(-phi)`` applied to its three sensors."""
    quat = dict(rec.quat)
    for e in estimates:
        if not e.detected:
            continue
        quat[e.sensor] = _turn_about_vertical(quat[e.sensor], -e.offset_rad)
        if e.sensor.endswith("_forearm") and e.axis_rad:  # the arm's facing: all three sensors
            arm = e.sensor.split("_")[0]
            for seg in ("upper_arm", "forearm", "hand"):
                s = sensor_name(arm, seg)
                quat[s] = _turn_about_vertical(quat[s], -e.axis_rad)
    return Recording(rec.time, quat, dict(rec.acc), dict(rec.gyr), rec.source)


def twist_mountings(calib: Calibration, estimates: list[HeadingEstimate]) -> Calibration:
    """Apply each detected wrist-axis angle phi as a twist of the forearm and hand mountings.

    ``R_SI' = Rx_S(phi) R_SI`` (x_S: the segment's long axis), so that in the base
    frame the rotations since zero become ``A Rx(-phi)`` and the wrist's flexion
    axis is the model's.
    """
    mounting = dict(calib.mounting)
    for e in estimates:
        if e.detected and e.sensor.endswith("_hand") and e.axis_rad:
            arm = e.sensor.split("_")[0]
            twist = Rotation.from_euler("x", e.axis_rad)
            for seg in ("forearm", "hand"):
                s = sensor_name(arm, seg)
                mounting[s] = (twist * Rotation.from_quat(mounting[s], scalar_first=True)).as_quat(scalar_first=True)
    return replace(calib, mounting=mounting)


def detect_and_correct(rec: Recording, calib_seconds: float, calib_start: float = 0.0,
                       calib_pose: str = "npose") -> tuple[Recording, list[HeadingEstimate]]:
    """Estimate heading offsets and return the corrected recording with the estimates."""
    estimates = estimate_heading_offsets(rec, calibrate(rec, calib_seconds, calib_start, calib_pose))
    return correct_heading(rec, estimates), estimates
