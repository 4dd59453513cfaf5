"""Deterministic evaluation of a learner on a fixed set of seeded episodes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualarm.training.rounds import OnStep, run_round
from dualarm.training.vector import EVAL_SEED_BASE, VectorEnv, seeds_for


@dataclass
class EvalResult:
    """Outcome of ``evaluate``.

    Attributes:
        success: (N,) bool per episode.
        returns: (N, A) summed rewards per episode and agent.
        steps: (N,) episode lengths.
    """

    success: np.ndarray
    returns: np.ndarray
    steps: np.ndarray

    @property
    def success_rate(self) -> float:
        return float(self.success.mean()) if len(self.success) else float("nan")

    @property
    def mean_return(self) -> float:
        """Mean over episodes of the return summed over agents."""
        return float(self.returns.sum(axis=1).mean()) if len(self.returns) else float("nan")


def evaluate(act, vec: VectorEnv, episodes: int, seed_base: int = EVAL_SEED_BASE,
             on_step: OnStep | None = None) -> EvalResult:
    """Run ``episodes`` episodes with a deterministic policy, ``vec.num_envs`` at a time.

    Args:
        act: maps observations (n, A, O) to actions (n, A, U) in [-1, 1].
        vec: the environment copies.
        episodes: how many; episode j is reset with ``seeds_for(seed_base, 0, episodes)[j]``.
        on_step: called after every step, as in ``run_round`` (e.g. to record transitions).
    """
    seeds = seeds_for(seed_base, 0, episodes)
    success = np.zeros(episodes, dtype=bool)
    returns = np.zeros((episodes, 2))
    steps = np.zeros(episodes, dtype=np.int64)
    for first in range(0, episodes, vec.num_envs):
        r = run_round(vec, seeds[first:first + vec.num_envs], act, on_step)
        rows = slice(first, first + len(r.steps))
        success[rows], returns[rows], steps[rows] = r.success, r.returns, r.steps
    return EvalResult(success, returns, steps)
