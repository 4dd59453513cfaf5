"""PettingZoo ``ParallelEnv`` of the dual-arm task: agents "left" and "right", one per arm.

Each agent observes its own arm (``BaxterReachGraspAlign`` layout), acts for its own arm
and gets its own reward (Eqs. 16-18). ``state()`` is the critic's global state
s = (s_left, s_right).
"""

from __future__ import annotations

import functools

import gymnasium
import numpy as np
from pettingzoo import ParallelEnv

from dualarm.envs import CoreView
from dualarm.envs.config import TaskConfig
from dualarm.kinematics import ARMS


class BaxterParallelEnv(CoreView, ParallelEnv):
    """Two agents, one per Baxter arm.

    Args:
        render_mode: None or "rgb_array".
        config: the task configuration (default ``TaskConfig()``).
        constraints: a ``ConstraintSet`` or a constraints file (for "single"/"multi").
        **overrides: ``TaskConfig`` fields to change.
    """

    metadata = {"name": "baxter_reach_grasp_align_v0", "render_modes": ["rgb_array"],
                "render_fps": 50, "is_parallelizable": True}

    def __init__(self, render_mode: str | None = None, config: TaskConfig | None = None,
                 constraints=None, **overrides):
        self._attach_core(render_mode, config, constraints, overrides)
        self.possible_agents = list(ARMS)
        self.agents = []
        self._obs_space = gymnasium.spaces.Box(-np.inf, np.inf, (self.core.obs_size,), np.float64)
        self._act_space = gymnasium.spaces.Box(-1.0, 1.0, (self.core.action_size,), np.float32)
        self._last_obs = np.zeros((2, self.core.obs_size))
        self._rng = np.random.default_rng()

    @functools.lru_cache(maxsize=None)
    def observation_space(self, agent: str) -> gymnasium.spaces.Box:
        self._check_agent(agent)
        return self._obs_space

    @functools.lru_cache(maxsize=None)
    def action_space(self, agent: str) -> gymnasium.spaces.Box:
        self._check_agent(agent)
        return self._act_space

    def _check_agent(self, agent: str) -> None:
        if agent not in self.possible_agents:
            raise ValueError(f"unknown agent {agent!r}: the agents are {self.possible_agents}")

    def reset(self, seed: int | None = None, options: dict | None = None):
        obs, info = self.core.reset(seed=seed)
        self.agents = list(self.possible_agents)
        self._last_obs = obs
        return self._split(obs), self._split_info(info)

    def step(self, actions: dict):
        if not self.agents:
            raise RuntimeError("the episode is over: call reset()")
        size = self.core.action_size
        stacked = np.empty((2, size))
        for row, agent in enumerate(self.possible_agents):
            if agent not in actions:
                raise ValueError(f"missing action for the {agent} arm (agents: {self.agents})")
            a = np.asarray(actions[agent], dtype=np.float64)
            if a.shape != (size,):
                raise ValueError(f"action of the {agent} arm must have shape ({size},) "
                                 f"({', '.join(self.core.action_names())}), got {a.shape}")
            stacked[row] = a
        unknown = set(actions) - set(self.possible_agents)
        if unknown:
            raise ValueError(f"actions for unknown agents {sorted(unknown)}")
        result = self.core.step(stacked)
        self._last_obs = result.obs
        rewards = {agent: float(result.reward[i]) for i, agent in enumerate(self.possible_agents)}
        terminations = {agent: result.terminated for agent in self.possible_agents}
        truncations = {agent: result.truncated for agent in self.possible_agents}
        obs, infos = self._split(result.obs), self._split_info(result.info)
        if result.terminated or result.truncated:
            self.agents = []
        return obs, rewards, terminations, truncations, infos

    def state(self) -> np.ndarray:
        """The critic's global state s = (s_left, s_right), shape (2 * obs_size,)."""
        return self._last_obs.reshape(-1).copy()

    def _split(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        return {agent: obs[i] for i, agent in enumerate(self.possible_agents)}

    def _split_info(self, info: dict) -> dict[str, dict]:
        """Per-agent info: the shared flags, and each arm's own sub-task and reward terms."""
        out = {}
        for i, agent in enumerate(self.possible_agents):
            out[agent] = {"is_success": info["is_success"], "physics_error": info["physics_error"],
                          "subtask": int(info["subtask"][i]), "reached": bool(info["reached"][i]),
                          "grasped": bool(info["grasped"][i]), "aligned": bool(info["aligned"][i]),
                          "reward_terms": {k: float(v[i]) for k, v in info["reward_terms"].items()}}
        return out
