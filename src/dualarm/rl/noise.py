"""Exploration noise added to the actors' actions: Gaussian (default) or Ornstein-Uhlenbeck."""

from __future__ import annotations

import numpy as np


class GaussianNoise:
    """Independent N(0, std^2) per step and action component."""

    def __init__(self, std: float):
        self.std = std

    def reset(self, envs: np.ndarray) -> None:
        """Start new episodes in the envs of the boolean mask (no state to reset)."""

    def sample(self, rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
        return rng.normal(0.0, self.std, size=shape)

    def state_dict(self) -> dict:
        return {}

    def load_state_dict(self, state: dict) -> None:
        pass


class OrnsteinUhlenbeckNoise:
    """Temporally correlated noise dx = theta (0 - x) dt + std sqrt(dt) dW, one process per env.

    Args:
        std: the diffusion scale sigma.
        theta: pull towards zero per unit time.
        dt: time step of the discretisation.
    """

    def __init__(self, std: float, theta: float = 0.15, dt: float = 1.0):
        self.std, self.theta, self.dt = std, theta, dt
        self.x: np.ndarray | None = None

    def reset(self, envs: np.ndarray) -> None:
        if self.x is not None:
            self.x[np.asarray(envs, dtype=bool)] = 0.0

    def sample(self, rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
        if self.x is None or self.x.shape != shape:
            self.x = np.zeros(shape)
        self.x = self.x + self.theta * -self.x * self.dt \
            + self.std * np.sqrt(self.dt) * rng.normal(size=shape)
        return self.x.copy()

    def state_dict(self) -> dict:
        return {} if self.x is None else {"x": self.x.tolist()}

    def load_state_dict(self, state: dict) -> None:
        self.x = np.asarray(state["x"]) if "x" in state else None


def make_noise(kind: str, std: float, theta: float):
    """The noise process named ``kind`` ("gaussian" or "ou")."""
    if kind == "gaussian":
        return GaussianNoise(std)
    if kind == "ou":
        return OrnsteinUhlenbeckNoise(std, theta)
    raise ValueError(f"noise must be 'gaussian' or 'ou', got {kind!r}")
