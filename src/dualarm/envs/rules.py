"""The task's rules, shared by the environment and the learner: the observation layout, the
fingers' geometry, the grasp and align predicates, and the goal functions a learner calls to
rewrite stored steps for other goals (lengths in m)."""

from __future__ import annotations

import numpy as np

from dualarm.envs.config import TaskConfig

#: Finger joint targets (m) fully open and fully closed, columns r_finger, l_finger.
FINGER_OPEN = np.array([-0.020833, 0.020833])
FINGER_CLOSED = np.array([0.0115, -0.0115])
_FINGER_TRAVEL = FINGER_CLOSED - FINGER_OPEN
#: Finger-pad gap (m) at finger joints (0, 0): the gap is this + l - r.
GAP_AT_ZERO = 2 * (0.01 + 0.01725 - 0.0047 - 0.0035)
UP = np.array([0.0, 0.0, 1.0])


def finger_gap(fingers: np.ndarray) -> np.ndarray:
    """Distance between the two finger pads (m) from finger joints (..., 2) ordered (r, l)."""
    return GAP_AT_ZERO + fingers[..., 1] - fingers[..., 0]


def finger_targets(closure: np.ndarray) -> np.ndarray:
    """Finger joint targets (..., 2) ordered (r, l) for grip closure (...,): 0 open .. 1 closed."""
    return FINGER_OPEN + np.asarray(closure)[..., None] * _FINGER_TRAVEL


def closed_gap(config: TaskConfig) -> float:
    """Largest finger gap (m) at which the fingers count as closed on a box."""
    return 2 * config.scene.box_half_size + config.grasp_gap_margin


#: Per-arm observation layout (paper Section 3.2.1.2): name -> size. "joint_angles" is
#: present only when the configuration asks for it.
OBS_LAYOUT = (
    ("grip_pos", 3),         # grip-site position, m (world)
    ("joint_angles", 7),     # s0..w2, rad
    ("object_pos", 3),       # box centre, m
    ("object_rel_pos", 3),   # box centre - grip site, m
    ("fingers", 2),          # finger joint positions (r, l), m
    ("object_quat", 4),      # box orientation (w, x, y, z), w >= 0
    ("object_linvel", 3),    # box linear velocity, m/s (world)
    ("object_angvel", 3),    # box angular velocity, rad/s (box frame)
    ("grip_linvel", 3),      # grip-site mean velocity over the last step, m/s
    ("finger_vel", 2),       # finger joint velocities, m/s
    ("target_pos", 3),       # the arm's target, m
)


def observation_layout(joint_angles: bool) -> dict[str, slice]:
    """Slices of each field in one arm's observation vector."""
    layout, start = {}, 0
    for name, size in OBS_LAYOUT:
        if name == "joint_angles" and not joint_angles:
            continue
        layout[name] = slice(start, start + size)
        start += size
    return layout


class GraspRule:
    """The task's grasp and align predicates from the physical state, one definition for the
    environment and for the learner's goal relabelling (lengths in m).

    A box is grasped when it is within ``grasp_tolerance`` of the grip site, the finger gap
    is at most the box width plus ``grasp_gap_margin`` and the box is ``lift_height`` above
    its resting height; it is aligned when grasped and within ``align_threshold`` of its target.
    """

    def __init__(self, config: TaskConfig):
        self.tolerance = config.grasp_tolerance
        self.reach_threshold = config.reach_threshold
        self.closed_gap = closed_gap(config)
        self.lifted_z = config.scene.table_height + config.scene.box_half_size + config.lift_height
        self.align_sq = config.align_threshold ** 2

    def held(self, rel, fingers, box):
        """The grasp predicate as 0/1 floats (...,), numpy or torch alike (for the learner's
        shaping potential): rel = box - grip (..., 3), finger joints (..., 2), box centres (..., 3)."""
        return self._grasped((rel * rel).sum(-1) ** 0.5, fingers, box) * 1.0

    def _grasped(self, to_box, fingers, box):
        """The grasp predicate (...,) bool from the grip-to-box distance (...,), the finger
        joints (..., 2) and the box centres (..., 3); numpy or torch."""
        return (to_box < self.tolerance) & (finger_gap(fingers) <= self.closed_gap) \
            & (box[..., 2] > self.lifted_z)

    def progress(self, to_box, grasped):
        """(reached, sub-task) (...,) from the grip-to-box distance and the grasp predicate
        (...,): reach is done within ``reach_threshold`` or once grasped; the sub-task is
        0 reach, 1 grasp, 2 align."""
        reached = grasped | (to_box < self.reach_threshold)
        return reached, reached.astype(np.int64) + grasped

    def __call__(self, rel: np.ndarray, fingers: np.ndarray, box: np.ndarray,
                 targets: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(distance grip site to box, grasped, aligned), each (...,) from rel = box - grip
        (..., 3), finger joints (..., 2), box centres (..., 3) and targets (..., 3)."""
        to_box = np.sqrt((rel * rel).sum(axis=-1))
        grasped = self._grasped(to_box, fingers, box)
        off = box - targets
        return to_box, grasped, grasped & ((off * off).sum(axis=-1) < self.align_sq)


class TaskGoals:
    """The task's goal functions, for a learner that rewrites stored steps for other goals
    (as SB3's HER buffer calls ``env.compute_reward``): what was achieved, and the terms of
    the reward (Eqs. 17-18) that depend on the goals, computed from stored observations
    (n, 2, O) laid out as ``observation_layout`` says. Lengths in m.

    Two kinds of goal: in the full task the arms' targets (``achieved_targets``: where the
    boxes went; ``target_terms``), in the reach task (``success_at="reach"``) the boxes
    (``achieved_boxes``: where the grip sites went; ``reach_reward``).
    """

    def __init__(self, config: TaskConfig, joint_angles: bool):
        self.config = config
        self.layout = observation_layout(joint_angles)
        self.rule = GraspRule(config)

    def achieved_targets(self, next_obs: np.ndarray) -> np.ndarray:
        """Box positions (n, 2, 3) m in observations (n, 2, O)."""
        return next_obs[..., self.layout["object_pos"]]

    def achieved_boxes(self, next_obs: np.ndarray) -> np.ndarray:
        """Grip-site positions (n, 2, 3) m in observations (n, 2, O)."""
        return next_obs[..., self.layout["grip_pos"]]

    def target_terms(self, next_obs: np.ndarray, targets: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
        """The target-dependent terms of a step that ended in ``next_obs`` (n, 2, O), for the
        targets (n, 2, 3): the distance term of each arm that holds its box (its goal is then
        the target, Eq. 17; 0 for the others) (n, 2), and success, both boxes held within
        ``align_threshold`` of their targets (Eq. 18) (n,) bool."""
        L = self.layout
        grip, box = next_obs[..., L["grip_pos"]], next_obs[..., L["object_pos"]]
        _, held, aligned = self.rule(next_obs[..., L["object_rel_pos"]], next_obs[..., L["fingers"]],
                                     box, targets)
        to_target = targets - grip
        distance = np.where(held, -np.sqrt((to_target * to_target).sum(-1)), 0.0)
        return distance, aligned.all(axis=-1)

    def reach_reward(self, obs: np.ndarray, next_obs: np.ndarray, boxes_before: np.ndarray,
                     boxes_after: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The reach task's reward of a step from ``obs`` to ``next_obs`` (n, 2, O) for boxes at
        ``boxes_before`` and ``boxes_after`` (n, 2, 3): -distance grip site to box + rg1 for an
        arm that comes within ``reach_threshold`` at this step + rc when both are within
        (n, 2), and that success (n,) bool. The guide term does not depend on the boxes."""
        c, grip = self.config, self.layout["grip_pos"]
        before = _distance(boxes_before - obs[..., grip]) < c.reach_threshold
        distance = _distance(boxes_after - next_obs[..., grip])
        after = distance < c.reach_threshold
        success = after.all(axis=-1)
        reward = -distance + c.reach_bonus * (after & ~before) + c.coordinate_bonus * success[:, None]
        return reward, success


def _distance(offset: np.ndarray) -> np.ndarray:
    return np.sqrt((offset * offset).sum(-1))
