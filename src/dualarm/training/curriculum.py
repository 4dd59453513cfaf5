"""A reverse curriculum over start states (after Florensa et al. 2017, "Reverse Curriculum
Generation for Reinforcement Learning"): train most where the task is being learned.

Training episodes may start each arm at a later sub-task (``TrainConfig.starts.probs``: at
reach, at its box with the fingers open, or holding its box). A task learned backwards
(hindsight targets teach the carry first) needs its starts to move backwards too: while the
episodes that begin holding the boxes fail, most starts should hold them; once those
succeed, most should begin at the boxes; once those succeed too, most should be normal.

Episodes are classed by their earliest arm start (0 reach, 1 grasp, 2 align: the sub-task
the harder arm still has to do). The *frontier* is the earliest class such that every later
class succeeds at least ``threshold`` of the time over its last ``window`` episodes; the
frontier class gets the largest of the base probabilities, the other two share the rest
equally. Evaluations are unaffected: they always start from the normal reset.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from dualarm.task import SUBTASKS

#: Start classes, earliest first: the sub-task at which an arm begins.
START_CLASSES = SUBTASKS


class ReverseCurriculum:
    """Start probabilities that move from the last sub-task towards the first as the later
    starts succeed.

    Args:
        base_probs: (reach, grasp, align) probabilities; their largest entry is the share
            of the frontier.
        threshold: success rate in (0, 1] at which a class counts as learned.
        window: episodes per class over which its success rate is measured; a class with
            fewer than half a window of episodes does not count as learned yet.
    """

    def __init__(self, base_probs, threshold: float, window: int = 64):
        p = np.asarray(base_probs, dtype=float)
        if not 0 < threshold <= 1:
            raise ValueError(f"the curriculum threshold must be in (0, 1], got {threshold}")
        self.share = float(p.max())
        self.threshold = threshold
        self.recent = [deque(maxlen=window) for _ in START_CLASSES]

    def record(self, starts: np.ndarray, success: np.ndarray) -> None:
        """Add finished episodes: ``starts`` (n, 2) each arm's start class, ``success`` (n,)."""
        for cls, ok in zip(np.asarray(starts).min(axis=1), np.asarray(success)):
            self.recent[int(cls)].append(bool(ok))

    def success_rates(self) -> list[float | None]:
        """Recent success rate per start class (None with fewer than half a window)."""
        return [float(np.mean(r)) if len(r) >= r.maxlen / 2 else None for r in self.recent]

    def frontier(self) -> int:
        """The earliest start class whose later classes are all learned."""
        rates = self.success_rates()
        k = len(START_CLASSES) - 1
        while k > 0 and rates[k] is not None and rates[k] >= self.threshold:
            k -= 1
        return k

    def probs(self) -> np.ndarray:
        """(reach, grasp, align) start probabilities for the next episodes, (3,)."""
        p = np.full(len(START_CLASSES), (1.0 - self.share) / (len(START_CLASSES) - 1))
        p[self.frontier()] = self.share
        return p

    def state_dict(self) -> dict:
        return {"recent": [list(r) for r in self.recent]}

    def load_state_dict(self, state: dict) -> None:
        for r, saved in zip(self.recent, state["recent"]):
            r.clear()
            r.extend(bool(x) for x in saved)
