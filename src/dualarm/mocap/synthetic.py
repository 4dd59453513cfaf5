"""Synthetic IMU recordings from joint-angle trajectories: the forward model of `joint_angles`.

Used to test the extraction (round trips), to make the built-in example recording,
and later to turn demonstrations into IMU files.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from dualarm.kinematics import ARMS, HUMAN_BASE_ROTATION, segment_rotations_in_base
from dualarm.mocap.joint_angles import ZERO_POSE_SEGMENT_ROTATION
from dualarm.mocap.recording import SEGMENTS, SENSORS, Recording, sensor_name


def random_mountings(rng: np.random.Generator) -> dict[str, Rotation]:
    """A uniformly random sensor-to-segment rotation R_SI for each of the six sensors."""
    return {s: Rotation.random(random_state=rng) for s in SENSORS}


def segment_orientations(q: np.ndarray) -> dict[str, Rotation]:
    """Segment frames in G for both arms.

    Args:
        q: (T, 14) human joint angles, rad (left q1..q7, right q1..q7).
    Returns:
        sensor name -> Rotation of length T, ``R_GS = B A_S B^T R^0``.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q.shape[-1] != 14:
        raise ValueError(f"joint angles must have 14 columns, got shape {q.shape}")
    B = HUMAN_BASE_ROTATION
    out = {}
    for i, arm in enumerate(ARMS):
        A = segment_rotations_in_base(q[:, 7 * i:7 * i + 7])
        for j, seg in enumerate(SEGMENTS):
            R = B @ A[:, j] @ B.T @ ZERO_POSE_SEGMENT_ROTATION[arm]
            out[sensor_name(arm, seg)] = Rotation.from_matrix(R)
    return out


def sensor_quaternions(q: np.ndarray, mountings: dict[str, Rotation] | None = None,
                       heading_offsets: dict[str, float] | None = None) -> dict[str, np.ndarray]:
    """Sensor orientations R_GI = H(delta) R_GS R_SI for joint angles ``q``.

    Args:
        q: (T, 14) joint angles, rad.
        mountings: sensor -> R_SI (identity where absent).
        heading_offsets: sensor -> heading offset delta (rad) of that sensor's own
            global frame about the vertical, as a magnetometer-free sensor has.
    Returns:
        sensor -> (T, 4) unit quaternions, scalar first.
    """
    mountings = mountings or {}
    heading_offsets = heading_offsets or {}
    out = {}
    for s, seg in segment_orientations(q).items():
        R = seg * mountings.get(s, Rotation.identity())
        if s in heading_offsets:
            R = Rotation.from_euler("z", heading_offsets[s]) * R
        out[s] = R.as_quat(scalar_first=True)
    return out


def synthetic_recording(time: np.ndarray, q: np.ndarray, *, mountings=None, heading_offsets=None,
                        noise_rad: float = 0.0, rng: np.random.Generator | None = None,
                        source: str = "<synthetic>") -> Recording:
    """A `Recording` whose sensors follow joint angles ``q`` exactly (plus optional noise).

    Args:
        time: (T,) seconds, strictly increasing.
        q: (T, 14) joint angles, rad.
        noise_rad: standard deviation (rad) of an independent small random rotation
            per sample and sensor (orientation noise), 0 for none.
    """
    quats = sensor_quaternions(q, mountings, heading_offsets)
    if noise_rad > 0:
        rng = rng or np.random.default_rng()
        for s, qs in quats.items():
            noise = Rotation.from_rotvec(rng.normal(0.0, noise_rad, (len(qs), 3)))
            quats[s] = (Rotation.from_quat(qs, scalar_first=True) * noise).as_quat(scalar_first=True)
    return Recording(np.asarray(time, dtype=float), quats, source=source)


def example_motion(duration_s: float = 12.0, rate_hz: float = 50.0, calib_s: float = 1.5) -> tuple[np.ndarray, np.ndarray]:
    """A smooth two-arm reach-and-lift motion after a still zero-pose window.

    Returns:
        time (T,) s and joint angles (T, 14) rad: both arms flex the shoulder and
        elbow, roll the forearm and bend the wrist, roughly mirror-symmetric,
        then return to the zero pose.
    """
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    s = np.clip((t - calib_s) / (duration_s - calib_s - 1.0), 0.0, 1.0)
    bump = np.sin(np.pi * s) ** 2          # 0 -> 1 -> 0, smooth at both ends
    wiggle = np.sin(3 * np.pi * s) * bump
    # Right arm: shoulder yaw, flexion, roll; elbow flexion, roll; wrist flexion, roll.
    right = np.stack([-0.35 * bump, 0.9 * bump, 0.3 * wiggle, 1.4 * bump,
                      0.8 * wiggle, 0.5 * bump, 0.3 * wiggle], axis=1)
    mirror = np.array([-1, 1, -1, 1, -1, 1, -1.0])  # q1, q3, q5, q7 flip for the other arm
    left = right * mirror * 0.9
    return t, np.concatenate([left, right], axis=1)


#: Heading offsets (rad) of the built-in example: two sensors without a shared heading.
EXAMPLE_HEADING_OFFSETS = {"right_forearm": np.deg2rad(25.0), "left_hand": np.deg2rad(-15.0)}


def example_recording(seed: int = 0) -> Recording:
    """The built-in example: `example_motion` seen through random sensor mountings,
    0.2 degrees of orientation noise and the heading offsets of ``EXAMPLE_HEADING_OFFSETS``.

    Deterministic for a given ``seed`` (the shipped file is ``seed=0``).
    """
    rng = np.random.default_rng(seed)
    t, q = example_motion()
    return synthetic_recording(t, q, mountings=random_mountings(rng), heading_offsets=EXAMPLE_HEADING_OFFSETS,
                               noise_rad=np.deg2rad(0.2), rng=rng, source="example_recording")
