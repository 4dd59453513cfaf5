"""Several copies of a two-agent environment behind one interface, stepped as a batch.

``BaxterVector`` drives ``BaxterBatch`` directly (one vectorised reward/observation pass
for all copies); ``ParallelEnvVector`` wraps any two-agent PettingZoo ``ParallelEnv`` with
continuous (Box) actions, one Python object per copy.

Shapes: n copies, A = 2 agents, O = the widest observation (narrower ones are zero-padded),
U = the widest action (actions of narrower agents are truncated).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import gymnasium
import numpy as np

from dualarm.envs.starts import NORMAL_START, StartDistribution
from dualarm.task import ARMS
from dualarm.training.config import TrainConfig
from dualarm.training.curriculum import START_CLASSES


@dataclass
class VectorStep:
    """The outcome of one batched step; rows of inactive copies are to be ignored.

    Attributes:
        obs: (n, A, O) observations after the step.
        reward: (n, A) rewards.
        terminated: (n,) the episode reached a terminal state (no bootstrapping).
        truncated: (n,) the episode was cut by a time limit.
        success: (n,) the task is solved.
        subtask: (n, A) int index of each agent's current sub-task, or None.
        terms: named reward terms, each (n, A) (empty when the env reports none).
    """

    obs: np.ndarray
    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    success: np.ndarray
    subtask: np.ndarray | None = None
    terms: dict[str, np.ndarray] = field(default_factory=dict)


class VectorEnv:
    """Interface of a batch of two-agent envs (see the module docstring for shapes)."""

    num_envs: int
    agents: tuple[str, ...]
    obs_sizes: tuple[int, ...]
    act_sizes: tuple[int, ...]
    term_names: tuple[str, ...] = ()
    has_subtasks: bool = False

    @property
    def obs_size(self) -> int:
        return max(self.obs_sizes)

    @property
    def act_size(self) -> int:
        return max(self.act_sizes)

    def reset(self, i: int, seed: int) -> np.ndarray:
        """Start an episode in copy i; returns its observation (A, O)."""
        raise NotImplementedError

    def step(self, actions: np.ndarray, active: np.ndarray) -> VectorStep:
        """Step the active copies with actions (n, A, U) in [-1, 1]."""
        raise NotImplementedError

    def close(self) -> None:
        pass


class BaxterVector(VectorEnv):
    """``num_envs`` copies of the Baxter reach-grasp-align task (``BaxterBatch``; ``starts``, a
    ``StartDistribution``, draws each arm's starting sub-task, for training curricula)."""

    term_names = ("distance", "guide", "goal", "coordinate")
    has_subtasks = True

    def __init__(self, config, constraints=None, num_envs: int = 1,
                 starts: StartDistribution = NORMAL_START):
        from dualarm.envs.baxter import BaxterBatch

        self.batch = BaxterBatch(config, constraints, num_envs, starts=starts)
        self.num_envs = num_envs
        self.agents = ARMS
        self.obs_sizes = (self.batch.obs_size,) * 2
        self.act_sizes = (self.batch.action_size,) * 2

    def reset(self, i: int, seed: int) -> np.ndarray:
        return self.batch.reset_env(i, seed)[0]

    def starts(self) -> np.ndarray:
        """Each copy's arms' start sub-tasks at its last reset, (num_envs, 2) (0 reach)."""
        return self.batch.start_kind.copy()

    def set_start_probs(self, probs) -> None:
        """Start probabilities (reach, grasp, align) of the next resets."""
        self.batch.set_start_probs(probs)

    def set_start_states(self, states) -> None:
        """Take the later starts of the next resets from ``states`` (``RecordedStates``)."""
        self.batch.set_start_states(states)

    def step(self, actions: np.ndarray, active: np.ndarray) -> VectorStep:
        r = self.batch.step_all(actions, active)
        return VectorStep(r.obs, r.reward, r.terminated, r.truncated, r.info["is_success"],
                          r.info["subtask"], r.info["reward_terms"])

    def close(self) -> None:
        self.batch.close()


class ParallelEnvVector(VectorEnv):
    """Copies of a two-agent PettingZoo ``ParallelEnv`` with Box observation and action spaces.

    The actor's actions in [-1, 1] are mapped linearly onto each agent's Box bounds. An
    episode ends when any agent terminates or is truncated; success is ``is_success`` in
    any agent's info.

    Args:
        make_env: builds one copy.
        num_envs: copies.
    """

    def __init__(self, make_env: Callable[[], object], num_envs: int = 1):
        self.envs = [make_env() for _ in range(num_envs)]
        env = self.envs[0]
        name = type(env).__name__
        agents = tuple(env.possible_agents)
        if len(agents) != 2:
            raise ValueError(f"{name} has {len(agents)} agents {list(agents)}: DADDPG needs two")
        self.num_envs = num_envs
        self.agents = agents
        obs_spaces = [env.observation_space(a) for a in agents]
        act_spaces = [env.action_space(a) for a in agents]
        for a, space in zip(agents, obs_spaces):
            if not isinstance(space, gymnasium.spaces.Box) or len(space.shape) != 1:
                raise ValueError(f"{name}: the observation space of agent {a!r} must be a flat "
                                 f"Box, got {space}")
        for a, space in zip(agents, act_spaces):
            if not isinstance(space, gymnasium.spaces.Box) or len(space.shape) != 1:
                raise ValueError(f"{name}: the action space of agent {a!r} must be a flat Box "
                                 f"(continuous actions), got {space}")
            if not (np.isfinite(space.low).all() and np.isfinite(space.high).all()):
                raise ValueError(f"{name}: the action space of agent {a!r} must be bounded")
        self.obs_sizes = tuple(int(s.shape[0]) for s in obs_spaces)
        self.act_sizes = tuple(int(s.shape[0]) for s in act_spaces)
        self._low = [np.asarray(s.low, dtype=float) for s in act_spaces]
        self._span = [np.asarray(s.high, dtype=float) - np.asarray(s.low, dtype=float)
                      for s in act_spaces]
        self._obs = np.zeros((num_envs, 2, self.obs_size))
        self.term_names = ()
        self.has_subtasks = False

    def _pack(self, obs: dict) -> np.ndarray:
        out = np.zeros((2, self.obs_size))
        for k, a in enumerate(self.agents):
            out[k, :self.obs_sizes[k]] = obs[a]
        return out

    def reset(self, i: int, seed: int) -> np.ndarray:
        obs, _ = self.envs[i].reset(seed=int(seed))
        self._obs[i] = self._pack(obs)
        return self._obs[i].copy()

    def step(self, actions: np.ndarray, active: np.ndarray) -> VectorStep:
        n = self.num_envs
        reward = np.zeros((n, 2))
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        success = np.zeros(n, dtype=bool)
        for i in np.flatnonzero(active):
            act = {a: self._low[k] + 0.5 * (np.clip(actions[i, k, :self.act_sizes[k]], -1, 1) + 1)
                   * self._span[k] for k, a in enumerate(self.agents)}
            obs, rew, term, trunc, info = self.envs[i].step(act)
            self._obs[i] = self._pack(obs)
            reward[i] = [rew[a] for a in self.agents]
            terminated[i] = any(term[a] for a in self.agents)
            truncated[i] = not terminated[i] and any(trunc[a] for a in self.agents)
            success[i] = any(bool(info.get(a, {}).get("is_success", False)) for a in self.agents)
        return VectorStep(self._obs.copy(), reward, terminated, truncated, success)

    def close(self) -> None:
        for env in self.envs:
            close = getattr(env, "close", None)
            if close:
                close()


def seeds_for(base: int, first: int, count: int) -> list[int]:
    """Reset seeds of episodes first .. first+count-1 of a run seeded ``base`` (32-bit ints).

    Episode k's seed depends only on (base, k), so a resumed run replays the same episodes.
    """
    return [int(np.random.SeedSequence([base, k]).generate_state(1)[0])
            for k in range(first, first + count)]


EVAL_SEED_BASE = 2_147_483_647
"""Evaluation episodes use ``seeds_for(EVAL_SEED_BASE, 0, N)``: the same set for every run."""
PROBE_SEED_BASE = 2_147_483_629
"""Curriculum probes (``TrainConfig.starts.probe``) draw their placements from this base,
the start class and the episode count: fresh placements at every probe, none shared with
training or evaluation."""


def make_vector_env(config: TrainConfig, num_envs: int,
                    make_env: Callable[[], object] | None = None, constraints=None,
                    training: bool = False, start: int = 0) -> VectorEnv:
    """Copies of the run's environment: the Baxter task, or ``make_env()`` (a ParallelEnv).

    ``constraints``: the run's ``ConstraintSet`` if already loaded (else read from the config).
    ``training``: the copies that collect training episodes, which start as
    ``config.starts`` says; otherwise (evaluation) every episode starts normally, or,
    with ``start`` k > 0, with both arms at sub-task ``START_CLASSES[k]`` (curriculum probes,
    ``dualarm eval --start``).
    """
    if make_env is not None:
        return ParallelEnvVector(make_env, num_envs)
    if constraints is None:
        constraints = config.load_constraints()
    starts = config.starts.distribution() if training else NORMAL_START
    if start:
        starts = StartDistribution(tuple(float(k == start) for k in range(len(START_CLASSES))))
    return BaxterVector(config.task_config(), constraints, num_envs, starts)
