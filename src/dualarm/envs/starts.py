"""Where a training episode begins: the start distribution, one object that the environment
draws each arm's first sub-task from (as robosuite injects one placement sampler).

Evaluations use ``NORMAL_START``: every arm at home, the task's normal reset.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from dualarm.errors import InputError


@dataclass(frozen=True)
class StartDistribution:
    """Per-arm probabilities of beginning an episode at each sub-task, and where reach starts
    begin.

    Attributes:
        probs: (reach, grasp, align), 3 non-negative numbers summing to 1: at home (reach),
            at its box with the fingers open (grasp done is still to do), or holding its box
            part of the way to its target (align). Drawn per arm, after the placement.
        approach: an arm that starts at reach begins a uniform fraction of the way from home
            to just above its box (gripper down, fingers open) instead of at home: starts that
            cover the approach, so that the value of being at the box can spread back along it.
    """

    probs: tuple[float, float, float] = (1.0, 0.0, 0.0)
    approach: bool = False

    def __post_init__(self):
        p = np.asarray(self.probs, dtype=float)
        if p.shape != (3,) or not np.isfinite(p).all() or (p < 0).any() or abs(p.sum() - 1) > 1e-6:
            raise InputError("probs: start probabilities must be 3 non-negative numbers (reach, "
                             f"grasp, align) that sum to 1, got {list(np.ravel(p))}")
        object.__setattr__(self, "probs", tuple(float(x) for x in p))

    @property
    def later(self) -> bool:
        """Whether an arm may begin past reach."""
        return self.probs[0] != 1.0

    def with_probs(self, probs) -> "StartDistribution":
        """The same distribution with other probabilities (a curriculum's move)."""
        return replace(self, probs=tuple(probs))

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        """(2,) int: the sub-task each arm begins at (0 reach, 1 grasp, 2 align). The normal
        reset draws nothing from ``rng``, so its episodes are those of a task without starts."""
        if not self.later:
            return np.zeros(2, dtype=np.int64)
        p = np.asarray(self.probs)
        return rng.choice(3, size=2, p=p / p.sum())


#: Every arm at home: evaluations, and the paper's training.
NORMAL_START = StartDistribution()
