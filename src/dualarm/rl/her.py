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
    """Replay batches with hindsight goals, and optionally the two arms' halves recombined.

    Args:
        buffer: a replay buffer filled episode by episode.
        achieved: the goals achieved in an observation (None with ``share`` 0).
        relabel: rewrites transitions for new goals (None with ``share`` 0).
        share: fraction of each batch relabelled (HER: 0.8, i.e. k = 4 future goals per
            real one).
        recombine: joins the left half of some rows with the right half of others
            (``dualarm.training.relabel.TargetRelabeller.recombine``; None with ``recombine_share`` 0).
        recombine_share: fraction of each batch whose right arm's half comes from another
            row of the batch, after the hindsight goals.
    """

    def __init__(self, buffer: ReplayBuffer, achieved: Achieved | None, relabel: Relabel | None,
                 share: float = 0.8, recombine=None, recombine_share: float = 0.0):
        if not 0 <= share <= 1:
            raise ValueError(f"the hindsight share must be in [0, 1], got {share}")
        if share > 0 and (achieved is None or relabel is None):
            raise ValueError("hindsight goals need the achieved and relabel functions")
        self.buffer, self.achieved, self.relabel, self.share = buffer, achieved, relabel, share
        if not 0 <= recombine_share <= 1 or (recombine_share > 0 and recombine is None):
            raise ValueError(f"recombine_share must be in [0, 1] and needs the recombine function, "
                             f"got {recombine_share}")
        self.recombine, self.recombine_share = recombine, float(recombine_share)

    def sample(self, rng: np.random.Generator, batch_size: int) -> dict[str, torch.Tensor]:
        """A uniform batch in which about ``share`` of the rows carry a future goal of their
        own episode (uniform over the transitions from this one to the episode's end)."""
        b = self.buffer
        idx = rng.integers(0, b.size, size=batch_size)
        batch = {k: v[idx] for k, v in b.data.items()}          # fancy indexing copies
        rows = np.flatnonzero(rng.random(batch_size) < self.share)
        if len(rows):
            offset = np.floor(rng.random(len(rows)) * (batch["left"][rows] + 1)).astype(np.int64)
            future = (idx[rows] + offset) % b.capacity
            goals = self.achieved(b.data["next_obs"][future])
            self.relabel(batch, rows, goals)
        if self.recombine_share > 0:      # drawn only then: the same batches without it
            joined = np.flatnonzero(rng.random(batch_size) < self.recombine_share)
            self.recombine(batch, joined, rng.integers(0, batch_size, size=len(joined)))
        return {k: torch.from_numpy(v) for k, v in batch.items()}
