"""Exploration added to the actors' actions: Gaussian noise independent per step."""

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
