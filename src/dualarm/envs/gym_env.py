"""Gymnasium environment ``dualarm/BaxterReachGraspAlign-v0``: both arms as one agent.

Observation: left arm's observation then the right's (flat, float64). Action: left
(dx, dy, dz, grip) then right, in [-1, 1] (float32 box; values outside are clipped).
Reward: the sum of both arms' rewards; ``info["rewards"]`` has each, ``info["is_success"]``
the task's success and ``info["reward_terms"]`` every term by name, per arm (left, right).
"""

from __future__ import annotations

import gymnasium
import numpy as np

from dualarm.envs import CoreView
from dualarm.envs.config import TaskConfig


class BaxterReachGraspAlignEnv(CoreView, gymnasium.Env):
    """Gymnasium view of the dual-arm task.

    Args:
        render_mode: None or "rgb_array".
        config: the task configuration (default ``TaskConfig()``).
        constraints: a ``ConstraintSet`` or a constraints file (for "single"/"multi").
        **overrides: ``TaskConfig`` fields to change, e.g. ``condition="multi"``.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 50}

    def __init__(self, render_mode: str | None = None, config: TaskConfig | None = None,
                 constraints=None, **overrides):
        self._attach_core(render_mode, config, constraints, overrides)
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.core.config.control_period)}
        n, a = self.core.obs_size, self.core.action_size
        self.observation_space = gymnasium.spaces.Box(-np.inf, np.inf, (2 * n,), np.float64)
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, (2 * a,), np.float32)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.core.rng = self.np_random      # the episode's placement follows Gymnasium's seeding
        obs, info = self.core.reset()
        return obs.reshape(-1), self._info(info, np.zeros(2))

    def step(self, action):
        a = np.asarray(action)
        size = self.core.action_size
        if a.shape != (2 * size,):
            names = ", ".join(self.core.action_names())
            raise ValueError(f"action must have {2 * size} values: left ({names}) then right, "
                             f"got shape {a.shape}")
        result = self.core.step(a.reshape(2, size))
        return (result.obs.reshape(-1), float(result.reward[0] + result.reward[1]),
                result.terminated, result.truncated, self._info(result.info, result.reward))

    @staticmethod
    def _info(info: dict, reward: np.ndarray) -> dict:
        info = dict(info)
        info["rewards"] = {"left": float(reward[0]), "right": float(reward[1])}
        return info
