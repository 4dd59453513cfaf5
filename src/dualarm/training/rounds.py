"""One round: an episode in each of the first n copies of a ``VectorEnv``, stepped together
until all have ended. Training and evaluation both run their episodes this way."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from dualarm.training.vector import VectorEnv, VectorStep

#: Maps observations (num_envs, A, O) to actions (num_envs, A, U) in [-1, 1].
Act = Callable[[np.ndarray], np.ndarray]
#: Called after every step with (obs before, actions, the step, indices of the copies stepped).
OnStep = Callable[[np.ndarray, np.ndarray, VectorStep, np.ndarray], None]


@dataclass
class Round:
    """Per-episode results of a round of n episodes (episode i ran in copy i).

    Attributes:
        first_obs: (n, A, O) observations after the resets.
        returns: (n, A) summed rewards.
        steps: (n,) episode lengths.
        success: (n,) the task was solved when the episode ended.
        subtask: (n, A) highest sub-task index reached (0 when the env reports none).
        terms: named reward terms summed over the episode, each (n, A).
    """

    first_obs: np.ndarray
    returns: np.ndarray
    steps: np.ndarray
    success: np.ndarray
    subtask: np.ndarray
    terms: dict[str, np.ndarray]


def run_round(vec: VectorEnv, seeds: list[int], act: Act, on_step: OnStep | None = None) -> Round:
    """Reset copy i with ``seeds[i]`` (i < n = len(seeds) <= num_envs) and step the copies
    whose episode goes on until every episode has ended; copies n.. stay idle."""
    n = len(seeds)
    obs = np.zeros((vec.num_envs, 2, vec.obs_size))
    active = np.zeros(vec.num_envs, dtype=bool)
    active[:n] = True
    for i in range(n):
        obs[i] = vec.reset(i, seeds[i])
    r = Round(obs[:n].copy(), np.zeros((n, 2)), np.zeros(n, dtype=np.int64),
              np.zeros(n, dtype=bool), np.zeros((n, 2), dtype=np.int64),
              {t: np.zeros((n, 2)) for t in vec.term_names})
    while active.any():
        actions = act(obs)
        step = vec.step(actions, active)
        live = np.flatnonzero(active)            # all < n: copies n.. are never active
        if on_step is not None:
            on_step(obs, actions, step, live)
        r.returns[live] += step.reward[live]
        r.steps[live] += 1
        for t in vec.term_names:
            r.terms[t][live] += step.terms[t][live]
        if step.subtask is not None:
            r.subtask[live] = np.maximum(r.subtask[live], step.subtask[live])
        ended = active & (step.terminated | step.truncated)
        r.success[ended[:n]] = step.success[:n][ended[:n]]
        active &= ~ended
        obs = step.obs
    return r
