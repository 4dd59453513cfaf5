"""Hindsight experience replay (Andrychowicz et al. 2017), the "future" strategy.

A share of every batch has its goals replaced by goals the agents achieved later in the
same episode, and its rewards recomputed for those goals, so that a task whose reward is
rare under the real goals still shows the critics what reaching a goal pays. The buffer
must hold whole episodes in order (``ReplayBuffer.add_episode``); what a goal is and how a
reward depends on it come from the task, as two functions.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import torch

from dualarm.rl.replay import ReplayBuffer

#: next_obs (n, A, O) -> the goals the agents achieved there, (n, A, G).
Achieved = Callable[[np.ndarray], np.ndarray]
#: (batch of numpy arrays, rows, goals (len(rows), A, G)) -> None: rewrite those rows'
#: obs, next_obs, rew and done in place as if the goals had been ``goals``.
Relabel = Callable[[dict, np.ndarray, np.ndarray], None]


class HindsightSampler:
    """Replay batches with hindsight goals, and optionally n-step returns.

    Args:
        buffer: a replay buffer filled episode by episode.
        achieved: the goals achieved in an observation (None with ``share`` 0).
        relabel: rewrites transitions for new goals (None with ``share`` 0).
        share: fraction of each batch relabelled (HER: 0.8, i.e. k = 4 future goals per
            real one).
        n_step: with n > 1 each row sums the rewards of up to n steps of its episode
            (``n_step_returns``); the batch then carries ``discount`` (B,), gamma^m.
        gamma: the discount of those sums (needed with n > 1).
        recombine: joins the left half of some rows with the right half of others
            (``dualarm.training.relabel.TargetRelabeller.recombine``; None with ``recombine_share`` 0).
        recombine_share: fraction of each batch whose right arm's half comes from another
            row of the batch, after the hindsight goals (1-step rows only).
    """

    def __init__(self, buffer: ReplayBuffer, achieved: Achieved | None, relabel: Relabel | None,
                 share: float = 0.8, n_step: int = 1, gamma: float | None = None,
                 recombine=None, recombine_share: float = 0.0):
        if not 0 <= share <= 1:
            raise ValueError(f"the hindsight share must be in [0, 1], got {share}")
        if share > 0 and (achieved is None or relabel is None):
            raise ValueError("hindsight goals need the achieved and relabel functions")
        if n_step < 1 or (n_step > 1 and gamma is None):
            raise ValueError(f"n_step must be >= 1 (and > 1 needs gamma), got {n_step}")
        self.buffer, self.achieved, self.relabel, self.share = buffer, achieved, relabel, share
        self.n_step, self.gamma = int(n_step), gamma
        if not 0 <= recombine_share <= 1 or (recombine_share > 0 and (recombine is None or n_step > 1)):
            raise ValueError(f"recombine_share must be in [0, 1] and needs the recombine function "
                             f"and 1-step rows, got {recombine_share} with n_step {n_step}")
        self.recombine, self.recombine_share = recombine, float(recombine_share)

    def sample(self, rng: np.random.Generator, batch_size: int) -> dict[str, torch.Tensor]:
        """A uniform batch in which about ``share`` of the rows carry a future goal of their
        own episode (uniform over the transitions from this one to the episode's end)."""
        b = self.buffer
        idx = rng.integers(0, b.size, size=batch_size)
        batch = {k: v[idx] for k, v in b.data.items()}          # fancy indexing copies
        rows = np.flatnonzero(rng.random(batch_size) < self.share)
        goals = None
        if len(rows):
            offset = np.floor(rng.random(len(rows)) * (batch["left"][rows] + 1)).astype(np.int64)
            future = (idx[rows] + offset) % b.capacity
            goals = self.achieved(b.data["next_obs"][future])
            self.relabel(batch, rows, goals)
        if self.recombine_share > 0:      # drawn only then: the same batches without it
            joined = np.flatnonzero(rng.random(batch_size) < self.recombine_share)
            self.recombine(batch, joined, rng.integers(0, batch_size, size=len(joined)))
        if self.n_step > 1:
            n_step_returns(batch, b, idx, self.n_step, self.gamma, self.relabel, rows, goals)
        return {k: torch.from_numpy(v) for k, v in batch.items()}


def n_step_returns(batch: dict, buffer: ReplayBuffer, idx: np.ndarray, n: int, gamma: float,
                   relabel: Relabel | None = None, rows: np.ndarray | None = None,
                   goals: np.ndarray | None = None) -> None:
    """Turn a batch of one-step transitions, drawn at buffer rows ``idx`` (B,), into m-step
    ones in place: rew becomes sum_{k<m} gamma^k r_{t+k}, next_obs and done those of step
    t+m-1, and a new ``discount`` (B,) float32 is gamma^m, with m = n, or fewer where the
    episode ends first (``done``, or no ``left`` transition after it). Batch rows ``rows``
    carry hindsight ``goals`` (len(rows), A, G): every later step is relabelled for them too,
    so that the m rewards are those of one goal. The batch's own first step must already be
    relabelled."""
    data, capacity = buffer.data, buffer.capacity
    relabelled = np.zeros(len(idx), dtype=bool)
    goal_of = None
    if rows is not None and len(rows):
        relabelled[rows] = True
        goal_of = np.zeros((len(idx),) + goals.shape[1:], dtype=goals.dtype)
        goal_of[rows] = goals
    discount = np.full(len(idx), gamma, dtype=np.float32)
    first_left = batch["left"]
    alive = (batch["done"] == 0) & (first_left >= 1)      # the episode goes on after step t
    for k in range(1, n):
        live = np.flatnonzero(alive)
        if not len(live):
            break
        at = (idx[live] + k) % capacity
        step = {key: data[key][at] for key in ("obs", "rew", "next_obs", "done")}
        own = np.flatnonzero(relabelled[live])
        if len(own):
            relabel(step, own, goal_of[live[own]])
        weight = discount[live].reshape((-1,) + (1,) * (step["rew"].ndim - 1))
        batch["rew"][live] += weight * step["rew"]
        batch["next_obs"][live] = step["next_obs"]
        batch["done"][live] = step["done"]
        discount[live] *= gamma
        alive[live] = (step["done"] == 0) & (first_left[live] >= k + 1)
    batch["discount"] = discount
