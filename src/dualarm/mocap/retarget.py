"""Human joint angles -> Baxter joint vector: the paper's identity mapping, clipped to Baxter's limits."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualarm.kinematics import BAXTER_JOINT_LIMITS, wrap_angle


@dataclass(frozen=True)
class Retargeted:
    """Baxter joint trajectories of both arms.

    Attributes:
        q: (T, 14) rad, left s0..w2 then right s0..w2, inside Baxter's limits.
        clipped_fraction: (14,) fraction of samples of each joint that were clipped.
    """

    q: np.ndarray
    clipped_fraction: np.ndarray


def to_baxter(q_human: np.ndarray) -> Retargeted:
    """Map human angles to Baxter (same angles, same posture: see `dualarm.kinematics`).

    Angles are first brought into [-pi, pi), since an unwrapped human roll of, say,
    370 degrees is the same posture as 10 degrees; then every joint is clipped to
    ``BAXTER_JOINT_LIMITS``.

    Args:
        q_human: (T, 14) human joint angles, rad.
    """
    q = np.asarray(q_human, dtype=float)
    if q.ndim != 2 or q.shape[1] != 14:
        raise ValueError(f"joint angles must have shape (T, 14), got {q.shape}")
    q = wrap_angle(q)
    limits = np.tile(BAXTER_JOINT_LIMITS, (2, 1))
    clipped = (q < limits[:, 0]) | (q > limits[:, 1])
    return Retargeted(np.clip(q, limits[:, 0], limits[:, 1]), clipped.mean(axis=0))
