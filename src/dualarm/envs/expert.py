"""A scripted expert for the reach-grasp-align task (cartesian control, both arms).

The expert reads only the observations, so it runs on the Gymnasium and PettingZoo
environments alike. Each arm, independently and without memory, picks the first
phase whose condition holds:

1. carry: the box is between the fingers and they are closed on it -> bring the box
   centre to the target, fingers closed;
2. close: the grip site is at the box centre -> stay, close the fingers;
3. descend: the grip site is above the box -> go down to the box centre, fingers open;
4. approach: otherwise -> go to ``hover`` above the box, fingers open.

Being memoryless, it retries by itself when a box slips out. It proves the task is
solvable, gives a baseline, and is the source of the demonstrations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualarm.envs.rules import closed_gap, finger_gap, observation_layout
from dualarm.envs.config import TaskConfig


@dataclass(frozen=True)
class ExpertConfig:
    """Tolerances of the scripted expert (m).

    Attributes:
        hover: height above the box centre from which to descend.
        above_tolerance: horizontal distance to the box under which the grip site may descend.
        at_box_tolerance: distance to the box centre under which the fingers close.
        held_tolerance: box-to-grip distance under which a box between closed fingers counts as held.
        gain: action per metre of error, in units of the maximum step (>1 makes up for lag).
    """

    hover: float = 0.06
    above_tolerance: float = 0.012
    at_box_tolerance: float = 0.012
    held_tolerance: float = 0.025
    gain: float = 1.5


class ScriptedExpert:
    """Observation -> action policy for both arms (cartesian control).

    Args:
        task: the task configuration of the environment (for the observation layout,
            the maximum step and the box size).
        config: the expert's tolerances.
    """

    def __init__(self, task: TaskConfig = TaskConfig(), config: ExpertConfig = ExpertConfig()):
        if task.control != "cartesian":
            raise ValueError("the scripted expert drives cartesian control only")
        self.task = task
        self.config = config
        self.layout = observation_layout(task.observes_joint_angles)
        self._closed_gap = closed_gap(task)

    def phases(self, obs: np.ndarray) -> np.ndarray:
        """Phase per arm (2,) int: 0 approach, 1 descend, 2 close, 3 carry."""
        c, L = self.config, self.layout
        rel = obs[:, L["object_rel_pos"]]                      # box - grip
        fingers = obs[:, L["fingers"]]
        gap = finger_gap(fingers)
        dist = np.linalg.norm(rel, axis=1)
        horizontal = np.linalg.norm(rel[:, :2], axis=1)
        held = (dist < c.held_tolerance) & (gap <= self._closed_gap)
        at_box = dist < c.at_box_tolerance
        above = horizontal < c.above_tolerance
        return np.where(held, 3, np.where(at_box, 2, np.where(above, 1, 0)))

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Actions (2, 4) in [-1, 1] for observations (2, obs_size), rows left, right."""
        obs = np.asarray(obs, dtype=float).reshape(2, -1)
        c, L = self.config, self.layout
        grip = obs[:, L["grip_pos"]]
        box = obs[:, L["object_pos"]]
        target = obs[:, L["target_pos"]]
        phase = self.phases(obs)
        goal = box.copy()
        goal[:, 2] += np.where(phase == 0, c.hover, 0.0)
        carry = phase == 3
        goal[carry] = target[carry] + (grip - box)[carry]     # box centre onto the target
        move = c.gain * (goal - grip) / self.task.max_cartesian_step
        grip_command = np.where(phase >= 2, 1.0, -1.0)
        return np.clip(np.concatenate([move, grip_command[:, None]], axis=1), -1.0, 1.0)
