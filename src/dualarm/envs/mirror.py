"""The task's left-right mirror symmetry, as a map on transitions (for mirrored replay).

Baxter, the table, the boxes' start range and the targets' range are symmetric about the
world's x-z plane (y = 0): reflecting a whole scene in it swaps the two arms and gives
another scene of the same task. Any transition the robot lives through has a mirror image
that it could have lived through, with the other arm doing what this one did. Storing both
gives each arm's agent the other arm's experience as well as its own (Kaleidoscope
Experience Replay, Lin et al. 2020, "Invariant Transform Experience Replay", which used
reflections with hindsight goals on the Fetch tasks and on a real Baxter).

Under the reflection (y -> -y), per arm:
- positions and linear velocities: (x, y, z) -> (x, -y, z);
- the box's orientation (w, x, y, z) -> (w, -x, y, -z) (the reflected rotation M R M), and
  its angular velocity in its own frame (x, y, z) -> (-x, y, -z);
- Baxter's joints s0, e0, w0, w2 (yaw and roll) change sign, s1, e1, w1 (pitch) keep it,
  as the two arms' rest postures show (``scene.REST_POSTURE``);
- the fingers close along world y, so the two fingers trade places: joints (r, l) -> (-l, -r),
  which keeps their gap;
- a Cartesian action (dx, dy, dz, grip) -> (dx, -dy, dz, grip); a joint action takes the
  joints' signs, grip unchanged.
Then the arms trade rows: the left arm's mirrored row becomes the right arm's.

Every reward term of Eq. 16-18 but the guide is symmetric (distances, rg1, rg2, rc) and
moves with its arm. The guide term is not: the constraints come from a person's two arms.
The mirrored transition is paid the guide of the mirrored joints under the constraints of
the arm they now belong to, in the sub-task that arm is in after the step (as the
environment pays it).
``tests/test_mirror.py`` checks the map against the physics: a mirrored scene driven by
mirrored actions follows the mirrored trajectory.
"""

from __future__ import annotations

import numpy as np

from dualarm.constraints.constraint_set import ConstraintSet
from dualarm.envs.rules import GraspRule, observation_layout
from dualarm.envs.config import TaskConfig
from dualarm.errors import InputError

#: Sign of each Baxter joint s0..w2 under the reflection.
JOINT_SIGNS = np.array([-1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0])
_FLIP_Y = np.array([1.0, -1.0, 1.0])
_QUAT_SIGNS = np.array([1.0, -1.0, 1.0, -1.0])
_ANGVEL_SIGNS = np.array([-1.0, 1.0, -1.0])


class TaskMirror:
    """Mirror images of the task's transitions (arms swapped, scene reflected in y = 0).

    Args:
        config: the task (its control mode, observation layout, thresholds, c0).
        constraints: the guide term's constraints (None for condition none).

    Raises:
        InputError: a guided condition without the joint angles in the observation (the
            mirrored guide term is computed from them).
    """

    def __init__(self, config: TaskConfig, constraints: ConstraintSet | None = None):
        joints = config.observes_joint_angles
        if constraints is not None and not joints:
            raise InputError("replay.mirror with a guided condition needs the joint angles in "
                             "the observation (task.joint_angles_in_obs: true): the mirrored "
                             "guide term is computed from them")
        self.config, self.constraints = config, constraints
        self.layout = observation_layout(joints)
        size = max(s.stop for s in self.layout.values())
        signs = np.ones(size)
        for name in ("grip_pos", "object_pos", "object_rel_pos", "object_linvel", "grip_linvel",
                     "target_pos"):
            signs[self.layout[name]] = _FLIP_Y
        signs[self.layout["object_quat"]] = _QUAT_SIGNS
        signs[self.layout["object_angvel"]] = _ANGVEL_SIGNS
        order = np.arange(size)
        for name in ("fingers", "finger_vel"):       # (r, l) -> (-l, -r)
            s = self.layout[name]
            order[s] = order[s][::-1]
            signs[s] = -1.0
        if joints:
            signs[self.layout["joint_angles"]] = JOINT_SIGNS
        self._obs_order, self._obs_signs = order, signs
        control_signs = _FLIP_Y if config.control == "cartesian" else JOINT_SIGNS
        self._act_signs = np.concatenate([control_signs, [1.0]])
        self._rule = GraspRule(config)
        self._c0 = np.asarray(config.guide_c0, dtype=float)

    def obs(self, obs: np.ndarray) -> np.ndarray:
        """Mirrored observations (..., 2, obs_size) of observations (..., 2, obs_size)."""
        return (obs[..., ::-1, :][..., self._obs_order] * self._obs_signs).astype(obs.dtype)

    def act(self, act: np.ndarray) -> np.ndarray:
        """Mirrored actions (..., 2, action_size) of actions (..., 2, action_size)."""
        return (act[..., ::-1, :] * self._act_signs).astype(act.dtype)

    def guide(self, next_obs: np.ndarray) -> np.ndarray:
        """The guide term (..., 2) the environment pays for arriving at observations
        ``next_obs`` (..., 2, obs_size): each arm's joints against its constraints in its
        sub-task there (reach 0, grasp 1 once within ``reach_threshold``, align 2 once held)."""
        L = self.layout
        box = next_obs[..., L["object_pos"]]
        # The environment's own predicates (the same distance and grasp); the target argument
        # only feeds the align flag, unused here.
        to_box, grasped, _ = self._rule(next_obs[..., L["object_rel_pos"]], next_obs[..., L["fingers"]],
                                        box, box)
        _, subtask = self._rule.progress(to_box, grasped)
        q = next_obs[..., L["joint_angles"]].reshape(next_obs.shape[:-2] + (14,))
        return self.constraints.guide_reward(q, subtask[..., 0], subtask[..., 1], self._c0)

    def reward(self, rew: np.ndarray, next_obs: np.ndarray) -> np.ndarray:
        """Mirrored rewards of transitions with rewards ``rew`` (n, 2) that arrived at
        ``next_obs`` (n, 2, obs_size)."""
        out = rew[:, ::-1].astype(np.float64)
        if self.constraints is not None:
            out += self.guide(self.obs(next_obs)) - self.guide(next_obs)[:, ::-1]
        return out.astype(rew.dtype)

    def episode(self, obs, act, rew, next_obs):
        """The mirror image of an episode's (or any batch's) transitions:
        (obs, act, rew, next_obs) with the shapes given."""
        return self.obs(obs), self.act(act), self.reward(rew, next_obs), self.obs(next_obs)
