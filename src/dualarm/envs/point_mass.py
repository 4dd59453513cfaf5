"""A two-agent toy task for testing learners: two point masses that must each reach a goal.

Each agent moves a point in the plane [-1, 1]^2 by up to ``max_step`` per step and is
rewarded by minus its distance to its own goal; both get ``bonus`` once when they are
both within ``radius`` of their goals, which is success and ends the episode. The right
agent also sees the left one's position, so the agents' observation widths differ
(4 and 6), as a generic two-agent ParallelEnv may.
"""

from __future__ import annotations

import functools

import gymnasium
import numpy as np
from pettingzoo import ParallelEnv


class TwoPointMassEnv(ParallelEnv):
    """PettingZoo ParallelEnv of two point masses (agents "left" and "right").

    Observations: left (x, y, goal_x, goal_y); right (x, y, goal_x, goal_y, left_x, left_y).
    Actions: (2,) in [-1, 1], a displacement of ``max_step`` * action.
    """

    metadata = {"name": "two_point_mass_v0", "render_modes": [], "is_parallelizable": True}

    def __init__(self, max_steps: int = 25, max_step: float = 0.15, radius: float = 0.1,
                 bonus: float = 10.0):
        self.possible_agents = ["left", "right"]
        self.agents = []
        self.max_steps, self.max_step, self.radius, self.bonus = max_steps, max_step, radius, bonus
        self._rng = np.random.default_rng()
        self.pos = np.zeros((2, 2))
        self.goal = np.zeros((2, 2))
        self.steps = 0

    @functools.lru_cache(maxsize=None)
    def observation_space(self, agent: str) -> gymnasium.spaces.Box:
        size = 4 if agent == "left" else 6
        return gymnasium.spaces.Box(-2.0, 2.0, (size,), np.float64)

    @functools.lru_cache(maxsize=None)
    def action_space(self, agent: str) -> gymnasium.spaces.Box:
        return gymnasium.spaces.Box(-1.0, 1.0, (2,), np.float32)

    def _obs(self) -> dict:
        return {"left": np.concatenate([self.pos[0], self.goal[0]]),
                "right": np.concatenate([self.pos[1], self.goal[1], self.pos[0]])}

    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.pos = self._rng.uniform(-1, 1, (2, 2))
        self.goal = self._rng.uniform(-1, 1, (2, 2))
        self.steps = 0
        self.agents = list(self.possible_agents)
        return self._obs(), {a: {} for a in self.agents}

    def step(self, actions: dict):
        move = np.stack([np.clip(np.asarray(actions[a], dtype=float), -1, 1) for a in self.possible_agents])
        self.pos = np.clip(self.pos + self.max_step * move, -1, 1)
        self.steps += 1
        dist = np.linalg.norm(self.pos - self.goal, axis=1)
        success = bool((dist < self.radius).all())
        reward = -dist + (self.bonus if success else 0.0)
        truncated = self.steps >= self.max_steps and not success
        obs = self._obs()
        agents = self.possible_agents
        rewards = {a: float(reward[i]) for i, a in enumerate(agents)}
        terms = {a: success for a in agents}
        truncs = {a: truncated for a in agents}
        infos = {a: {"is_success": success} for a in agents}
        if success or truncated:
            self.agents = []
        return obs, rewards, terms, truncs, infos
