"""What to check before training: how much of Baxter's joint box each segment leaves, and how
often given joint angles (the scripted expert's: ``dualarm.envs.rollout.expert_rollouts``)
stay inside."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualarm.constraints.constraint_set import ConstraintSet
from dualarm.kinematics import BAXTER_JOINT_LIMITS
from dualarm.task import JOINTS_PER_ARM

_N_ARM = JOINTS_PER_ARM


def arm_volume_fractions(cs: ConstraintSet, limits: np.ndarray = BAXTER_JOINT_LIMITS) -> np.ndarray:
    """(S, 2) fraction of one arm's 7-D joint box (left, right) each segment leaves."""
    w = cs.width_fractions(limits)
    return np.stack([w[:, :_N_ARM].prod(axis=1), w[:, _N_ARM:].prod(axis=1)], axis=1)


@dataclass(frozen=True)
class InsideReport:
    """How often joint angles stay inside the constraints of their arm's current segment.

    Attributes:
        fraction: (S, 14) for segment s and joint k, the share of rows whose arm (of joint
            k) is in a sub-task of segment s with joint k inside the bounds; NaN where no row is.
        all_joints: (S, 2) the share of those rows with all seven joints of the arm inside
            (what earns an arm the full guide reward +7 c0).
        count: (S, 2) rows per segment and arm.
    """

    fraction: np.ndarray
    all_joints: np.ndarray
    count: np.ndarray


def expert_inside_fractions(cs: ConstraintSet, q: np.ndarray, subtasks: np.ndarray) -> InsideReport:
    """Check joint angles against the segment each arm is in (as the guide reward does).

    Args:
        cs: the constraints.
        q: (N, 14) joint angles, rad.
        subtasks: (N, 2) sub-task index (0 reach, 1 grasp, 2 align) of the left and right arm.
    Returns:
        :class:`InsideReport`.
    """
    subtasks = np.asarray(subtasks)
    inside = cs.inside(q, subtasks[:, 0], subtasks[:, 1])                      # (N, 14)
    seg = cs.segment_of_subtask[subtasks]                                      # (N, 2)
    S = len(cs.segments)
    frac = np.full((S, 2 * _N_ARM), np.nan)
    every = np.full((S, 2), np.nan)
    count = np.zeros((S, 2), dtype=np.int64)
    for s in range(S):
        for a in range(2):
            rows = seg[:, a] == s
            count[s, a] = rows.sum()
            if count[s, a]:
                arm_inside = inside[rows, _N_ARM * a:_N_ARM * (a + 1)]
                frac[s, _N_ARM * a:_N_ARM * (a + 1)] = arm_inside.mean(axis=0)
                every[s, a] = arm_inside.all(axis=1).mean()
    return InsideReport(frac, every, count)
