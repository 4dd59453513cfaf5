"""Calibration (paper Eq. 1-2) and human joint-angle extraction (Eq. 3-10), both arms.

The convention, written once
----------------------------
* Global frame G: the person faces +x, z points up (y to the person's left).
* Zero pose (q = 0): standing, both arms hanging straight down. The right arm's
  segment frames (upper arm U, forearm F, palm P) are then the paper's
  ``R^0 = [0 0 1; 0 1 0; -1 0 0]`` (segment x down, y along +y_G, z along +x_G);
  the left arm's are their mirror image through the sagittal plane,
  ``M R^0 M`` with ``M = diag(1, -1, 1)`` (which happens to equal R^0).
* Calibration (Eq. 1): the mounting of sensor I on segment S is
  ``R_SI = (R^0_GS)^T mean(R_GI)`` over a window in the zero pose, with the
  rotation mean of :meth:`scipy.spatial.transform.Rotation.mean` (the chordal L2
  mean, Markley et al. 2007), not one sample. Eq. 2 then gives
  ``R_GS(t) = R_GI(t) R_SI^T``.
* Joints. The paper's Eqs. 3, 6 and 9 are not consistent with its D-H table or
  with R^0, so we derive the extraction from the D-H chain itself
  (:mod:`dualarm.kinematics`): in the arm's base frame B (``HUMAN_BASE_ROTATION``),
  the rotation of each segment since the zero pose, ``A_S = B^T R_GS(t) (R^0)^T B``, is

      A_U = Rz(q1) Ry(q2) Rx(q3)          (shoulder: yaw, pitch, roll)
      A_U^T A_F = Ry(q4) Rx(q5)           (elbow: flexion, forearm roll)
      A_F^T A_P = Ry(q6) Rx(q7)           (wrist: flexion, hand roll)

  so ``R^0`` cancels and the angles depend only on each sensor's rotation since
  the calibration window. q2 > 0 is shoulder flexion, q4 > 0 elbow flexion.
* Extraction without division by cos(q2): ``q2 = atan2(-r31, hypot(r11, r21))``,
  ``q1 = atan2(r21, r11)``, ``q3 = atan2(r32, r33)``. At the singular pose
  (|cos q2| < ``GIMBAL_EPS``) only q1 -+ q3 is defined: q1 keeps its previous value.
  The second solution (q1 + pi, pi - q2, q3 + pi) is followed when a motion passes
  through the singular pose, and every angle is unwrapped, so the angles are
  continuous in time (no jumps of pi or 2 pi).
* Residual. A 2-DOF joint cannot represent every relative rotation: q4 is read
  from the direction of the child's long axis, q5 from the direction of the
  flexion axis seen from the child, and the residual is the angle (rad) of the
  rotation left unexplained, ``angle((Ry(q4) Rx(q5))^T R_rel)``. Large residuals
  mean sensor slip, a bad calibration or a heading offset (see ``heading.py``).
"""

from __future__ import annotations

from dataclasses import dataclass
import warnings

import numpy as np
from scipy.spatial.transform import Rotation

from dualarm.errors import InputError
from dualarm.kinematics import ARMS, HUMAN_BASE_ROTATION, packed, wrap_angle
from dualarm.mocap.recording import SEGMENTS, Recording, sensor_name

#: The paper's R^0: right-arm segment frames in G at the zero pose.
R0_RIGHT = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
_MIRROR_SAGITTAL = np.diag([1.0, -1.0, 1.0])
#: Left-arm segment frames at the zero pose: the mirror image of R0_RIGHT.
R0_LEFT = _MIRROR_SAGITTAL @ R0_RIGHT @ _MIRROR_SAGITTAL
ZERO_POSE_SEGMENT_ROTATION = {"left": R0_LEFT, "right": R0_RIGHT}

#: Calibration poses: ``npose`` is the zero pose (arms hanging by the sides); ``tpose`` has
#: both arms raised sideways to the horizontal (abducted 90 degrees about the forward axis),
#: the rest pose of most BVH skeletons and a common start of suit recordings. In either, the
#: palms may face forward, in or down: the forearm's twist is found by the heading fit.
CALIB_POSES: tuple[str, ...] = ("npose", "tpose")
POSE_NAMES = {"npose": "zero pose", "tpose": "T-pose"}


def calibration_pose_rotation(arm: str, pose: str = "npose") -> np.ndarray:
    """(3, 3) the segment frames of ``arm`` in G in the calibration ``pose`` (all three alike).

    ``npose``: ``R^0`` of the zero pose. ``tpose``: ``Rx(-+90 deg) R^0``, the arm turned out
    to the side (the right arm to -y_G, the left to +y_G) about the forward axis x_G.
    """
    if pose not in CALIB_POSES:
        raise InputError(f"calibration pose must be one of {', '.join(CALIB_POSES)}, got {pose!r}")
    R0 = ZERO_POSE_SEGMENT_ROTATION[arm]
    if pose == "npose":
        return R0
    angle = np.pi / 2 if arm == "left" else -np.pi / 2
    return Rotation.from_euler("x", angle).as_matrix() @ R0


#: Below this |cos q2| the shoulder is treated as singular (q1 held, q1 -+ q3 solved).
GIMBAL_EPS = 1e-9
#: Default length of the calibration window at the start of a recording (s).
DEFAULT_CALIB_SECONDS = 1.0
#: A sensor turning more than this (rad) inside the calibration window gets a warning.
CALIB_STILLNESS_WARN = np.deg2rad(5.0)

JOINT_COLUMNS: tuple[str, ...] = tuple(f"{arm}_q{k}" for arm in ARMS for k in range(1, 8))
RESIDUAL_COLUMNS: tuple[str, ...] = ("left_elbow", "left_wrist", "right_elbow", "right_wrist")


@dataclass(frozen=True)
class Calibration:
    """Sensor-to-segment mountings estimated from a zero-pose window (Eq. 1).

    Attributes:
        mounting: sensor name -> (4,) quaternion (w, x, y, z) of R_SI, the sensor
            frame in its segment frame.
        window_s: (start, end) of the calibration window, seconds of recording time.
        spread: sensor name -> largest angle (rad) between a window sample and the
            window mean; a still sensor gives noise level only.
    """

    mounting: dict[str, np.ndarray]
    window_s: tuple[float, float]
    spread: dict[str, float]


@dataclass(frozen=True)
class JointAngles:
    """Human joint angles of both arms over time.

    Attributes:
        time: (T,) seconds.
        q: (T, 14) rad, columns ``JOINT_COLUMNS`` (left q1..q7, right q1..q7).
        residual: (T, 4) rad, unexplained rotation of ``RESIDUAL_COLUMNS``.
    """

    time: np.ndarray
    q: np.ndarray
    residual: np.ndarray

    def arm(self, side: str) -> np.ndarray:
        """(T, 7) joint angles of ``side``."""
        return self.q[:, 0:7] if side == "left" else self.q[:, 7:14]


def calibration_window(rec: Recording, seconds: float, start: float = 0.0) -> np.ndarray:
    """Indices of the samples from ``start`` to ``start + seconds`` after the first sample.

    Raises:
        InputError: if ``seconds`` is not positive, ``start`` is negative, or the
            window ends after the recording.
    """
    if not np.isfinite(seconds) or seconds <= 0:
        raise InputError(f"calibration window must be a positive number of seconds, got {seconds}",
                         source=rec.source)
    if not np.isfinite(start) or start < 0:
        raise InputError(f"calibration start must be >= 0 s, got {start}", source=rec.source)
    if start + seconds > rec.duration + 1e-9:
        what = f"{seconds:g} s" if start == 0 else f"{start:g} + {seconds:g} s"
        raise InputError(f"calibration window of {what} is longer than the recording "
                         f"({rec.duration:g} s)", source=rec.source)
    elapsed = rec.time - rec.time[0]
    return np.flatnonzero((elapsed >= start - 1e-9) & (elapsed <= start + seconds + 1e-9))


def calibrate(rec: Recording, seconds: float = DEFAULT_CALIB_SECONDS, start: float = 0.0,
              pose: str = "npose") -> Calibration:
    """Sensor-to-segment mountings from the calibration window of ``rec`` (Eq. 1).

    ``R_SI = (R^pose)^T mean(R_GI)``, with ``R^pose`` from :func:`calibration_pose_rotation`
    (``R^0`` for the zero pose): the joint angles in the window are then those of the pose.

    Args:
        seconds: length of the window, s.
        start: seconds from the first sample to the start of the window (0: the
            recording starts in the pose; later, e.g., when the orientation
            filter needs time to converge).
        pose: the pose held in the window, one of :data:`CALIB_POSES`.

    Warns (``UserWarning``) when a sensor turns more than 5 degrees inside the window.
    """
    idx = calibration_window(rec, seconds, start)
    mounting, spread = {}, {}
    for arm in ARMS:
        zero = Rotation.from_matrix(calibration_pose_rotation(arm, pose))
        for seg in SEGMENTS:
            s = sensor_name(arm, seg)
            samples = Rotation.from_quat(rec.quat[s][idx], scalar_first=True)
            mean = samples.mean()
            spread[s] = float((mean.inv() * samples).magnitude().max())
            mounting[s] = (zero.inv() * mean).as_quat(scalar_first=True)
            if spread[s] > CALIB_STILLNESS_WARN:
                warnings.warn(f"{rec.source}: sensor {s} turned {np.rad2deg(spread[s]):.1f} deg inside "
                              f"the calibration window; is the person still in the {POSE_NAMES[pose]}?",
                              stacklevel=2)
    return Calibration(mounting, (float(rec.time[idx[0]]), float(rec.time[idx[-1]])), spread)


def segment_rotations_since_zero(rec: Recording, calib: Calibration) -> dict[str, np.ndarray]:
    """Each segment's rotation since the zero pose, in its arm's base frame.

    Eq. 2, ``R_GS(t) = R_GI(t) R_SI^T``, then ``A_S = B^T R_GS(t) (R^0)^T B``.

    Returns:
        arm -> (3, T, 3, 3): index 0 is the segment (upper arm, forearm, hand).
    """
    B = HUMAN_BASE_ROTATION
    out = {}
    for arm in ARMS:
        right_factor = ZERO_POSE_SEGMENT_ROTATION[arm].T @ B
        A = np.empty((3, rec.n_samples, 3, 3))
        for j, seg in enumerate(SEGMENTS):
            s = sensor_name(arm, seg)
            # Matrices, not Rotation products: scipy's broadcast product is ~50x slower here.
            sensor = Rotation.from_quat(rec.quat[s], scalar_first=True).as_matrix()
            mount = Rotation.from_quat(calib.mounting[s], scalar_first=True).as_matrix()
            np.matmul(B.T, sensor @ (mount.T @ right_factor), out=A[j])
        out[arm] = A
    return out


def entries_over_time(R: np.ndarray) -> np.ndarray:
    """(T, 3, 3) rotations -> (3, 3, T) contiguous copy: ``[i, j]`` is entry (i, j) over time,
    a contiguous row that numpy's arctan2 treats the same in every run (``packed``)."""
    return packed(np.moveaxis(R, 0, -1))


def shoulder_angles(A_upper: np.ndarray) -> np.ndarray:
    """Invert ``A_U = Rz(q1) Ry(q2) Rx(q3)`` over time, continuously.

    Args:
        A_upper: (T, 3, 3) upper-arm rotations since the zero pose, base frame.
    Returns:
        (T, 3) q1, q2, q3 in rad, unwrapped along time.
    """
    R = entries_over_time(A_upper)
    cos_q2 = np.hypot(R[0, 0], R[1, 0])
    q2 = np.arctan2(-R[2, 0], cos_q2)
    q1 = np.arctan2(R[1, 0], R[0, 0])
    q3 = np.arctan2(R[2, 1], R[2, 2])
    singular = cos_q2 < GIMBAL_EPS
    if singular.any():
        # Only q1 - q3 (q2 = +pi/2) or q1 + q3 (q2 = -pi/2) is defined: hold q1.
        last_regular = np.where(singular, -1, np.arange(len(q1)))
        np.maximum.accumulate(last_regular, out=last_regular)
        held = np.where(last_regular >= 0, q1[np.maximum(last_regular, 0)], 0.0)
        q1 = np.where(singular, held, q1)
        up = q2 > 0
        combo = np.where(up, np.arctan2(R[0, 1], R[0, 2]), np.arctan2(-R[0, 1], -R[0, 2]))
        q3 = np.where(singular, np.where(up, combo + q1, combo - q1), q3)
    # Follow the second solution (q1+pi, pi-q2, q3+pi) where that is the smaller step.
    if len(q1) > 1:
        same = np.abs(wrap_angle(np.diff(q1))) + np.abs(np.diff(q2)) + np.abs(wrap_angle(np.diff(q3)))
        other = (np.abs(wrap_angle(q1[1:] + np.pi - q1[:-1])) + np.abs(wrap_angle(np.pi - q2[1:] - q2[:-1]))
                 + np.abs(wrap_angle(q3[1:] + np.pi - q3[:-1])))
        flipped = np.concatenate([[False], np.cumsum(other < same) % 2 == 1])
        q1 = np.where(flipped, q1 + np.pi, q1)
        q2 = np.where(flipped, np.pi - q2, q2)
        q3 = np.where(flipped, q3 + np.pi, q3)
    return np.unwrap(np.stack([q1, q2, q3], axis=1), axis=0)


def two_dof_angles(R_rel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Invert ``R_rel = Ry(a) Rx(b)`` (elbow or wrist) over time.

    Args:
        R_rel: (T, 3, 3) rotation of the child segment in the parent's frame.
    Returns:
        angles (T, 2) = a, b in rad, unwrapped along time; residual (T,) in rad,
        the angle of the rotation that Ry(a) Rx(b) leaves unexplained.
    """
    R = R_rel
    entries = entries_over_time(R)
    a = np.arctan2(-entries[2, 0], entries[0, 0])
    b = np.arctan2(-entries[1, 2], entries[1, 1])
    # Residual E = Rx(-b) Ry(-a) R written out entry by entry (no (T, 3, 3) temporaries):
    # P = Ry(-a) R has rows P0 = ca R0 - sa R2, P1 = R1, P2 = sa R0 + ca R2.
    ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
    P0 = ca[:, None] * R[:, 0] - sa[:, None] * R[:, 2]
    P1 = R[:, 1]
    P2 = sa[:, None] * R[:, 0] + ca[:, None] * R[:, 2]
    trace = P0[:, 0] + cb * P1[:, 1] + sb * P2[:, 1] - sb * P1[:, 2] + cb * P2[:, 2]
    vx = (-sb * P1[:, 1] + cb * P2[:, 1]) - (cb * P1[:, 2] + sb * P2[:, 2])
    vy = P0[:, 2] - (-sb * P1[:, 0] + cb * P2[:, 0])
    vz = (cb * P1[:, 0] + sb * P2[:, 0]) - P0[:, 1]
    residual = np.arctan2(np.sqrt(vx * vx + vy * vy + vz * vz) / 2, (trace - 1) / 2)
    return np.unwrap(np.stack([a, b], axis=1), axis=0), residual


def arm_angles(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(3, T, 3, 3) segment rotations since zero (base frame) -> (T, 7) angles, (T, 2) residuals."""
    A_u, A_f, A_p = A
    shoulder = shoulder_angles(A_u)
    elbow, r_elbow = two_dof_angles(np.swapaxes(A_u, -1, -2) @ A_f)
    wrist, r_wrist = two_dof_angles(np.swapaxes(A_f, -1, -2) @ A_p)
    return np.concatenate([shoulder, elbow, wrist], axis=1), np.stack([r_elbow, r_wrist], axis=1)


def joint_angles(rec: Recording, calib: Calibration) -> JointAngles:
    """Human joint angles of both arms (Eqs. 2-10 in the convention above).

    Args:
        rec: the recording (sensor orientations in G).
        calib: mountings from :func:`calibrate`.
    Returns:
        JointAngles with q (T, 14) rad and residual (T, 4) rad.
    """
    A = segment_rotations_since_zero(rec, calib)
    q, res = zip(*(arm_angles(A[arm]) for arm in ARMS))
    return JointAngles(rec.time.copy(), np.concatenate(q, axis=1), np.concatenate(res, axis=1))
