"""Exploration added to the actors' actions: Gaussian noise independent per step, and
grip commands held for several steps (temporally extended exploration)."""

from __future__ import annotations

import numpy as np


class GaussianNoise:
    """Independent N(0, std^2) per step and action component (std in action units)."""

    def __init__(self, std: float):
        self.std = std

    def reset(self, envs: np.ndarray) -> None:
        """Start new episodes in the envs of the boolean mask (no state to reset)."""

    def sample(self, rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
        """(shape) draws from ``rng``."""
        return rng.normal(0.0, self.std, size=shape)


class HeldGrip:
    """Grip commands held for several steps: epsilon-z-greedy (Dabney, Ostrovski and
    Barreto 2021) on one action component per agent.

    In each step, an agent that holds nothing starts, with probability ``eps``, to hold a
    uniformly random grip command in [-1, 1] for n steps, the step it starts in included;
    the command replaces the agent's grip while it lasts. Per-step noise cannot keep a hand
    open for the few steps a descent onto a box needs once the policy closes it by default:
    a hold can. n is uniform on 1..``max_steps``; Dabney et al.'s zeta(2) durations have a
    mean under 2 steps at max_steps = 10, shorter than that descent.

    State: the held commands and the steps left, (N, A) each for N environments; ``reset``
    clears it for the environments that start new episodes.
    """

    def __init__(self, eps: float, max_steps: int):
        self.eps = eps
        self.max_steps = max_steps
        self.value = np.zeros((0, 0))
        self.left = np.zeros((0, 0), dtype=np.int64)

    def reset(self, envs: np.ndarray) -> None:
        """Drop the holds of the envs of the boolean mask (N,)."""
        if len(self.left) == len(envs):
            self.left[np.asarray(envs, dtype=bool)] = 0

    def apply(self, rng: np.random.Generator, actions: np.ndarray, grip_columns: np.ndarray,
              eps: np.ndarray | float | None = None) -> np.ndarray:
        """Actions (N, A, U) with the held grips in place: ``grip_columns`` (A, U) marks each
        agent's grip component; ``eps`` (N, A), if given, is the chance to start a hold per
        environment and agent in place of ``self.eps``. One step of every hold elapses."""
        n, a = actions.shape[:2]
        if self.left.shape != (n, a):
            self.value, self.left = np.zeros((n, a)), np.zeros((n, a), dtype=np.int64)
        start = (self.left == 0) & (rng.random((n, a)) < (self.eps if eps is None else eps))
        self.value = np.where(start, rng.uniform(-1.0, 1.0, (n, a)), self.value)
        self.left = np.where(start, rng.integers(1, self.max_steps + 1, (n, a)), self.left)
        held = self.left > 0
        out = np.where(held[..., None] & grip_columns[None], self.value[..., None], actions)
        self.left = np.maximum(self.left - 1, 0)
        return out
