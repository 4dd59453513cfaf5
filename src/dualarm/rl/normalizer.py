"""Running mean and standard deviation of each agent's observations, clipped after scaling."""

from __future__ import annotations

import numpy as np
import torch


class RunningNormalizer:
    """Per-agent, per-feature running statistics: (x - mean) / std, clipped to +-clip.

    Statistics are kept in float64 sums (exact to merge, no drift); ``normalize`` runs in
    torch float32.

    Args:
        num_agents, size: statistics have shape (num_agents, size).
        clip: bound on the normalised values.
        eps: floor of the standard deviation (a constant feature maps to 0).
    """

    def __init__(self, num_agents: int, size: int, clip: float = 5.0, eps: float = 1e-2):
        self.clip = clip
        self.eps = eps
        self.count = 0
        self.sum = np.zeros((num_agents, size))
        self.sum_sq = np.zeros((num_agents, size))
        self.mean = torch.zeros(num_agents, size)
        self.std = torch.ones(num_agents, size)

    def update(self, x: np.ndarray) -> None:
        """Add observations x (N, num_agents, size) to the statistics."""
        x = np.asarray(x, dtype=np.float64)
        self.count += x.shape[0]
        self.sum += x.sum(axis=0)
        self.sum_sq += (x * x).sum(axis=0)
        mean = self.sum / self.count
        var = np.maximum(self.sum_sq / self.count - mean * mean, 0.0)
        self.mean = torch.as_tensor(mean, dtype=torch.float32)
        self.std = torch.as_tensor(np.maximum(np.sqrt(var), self.eps), dtype=torch.float32)

    def normalize(self, x: torch.Tensor) -> torch.Tensor:
        """x (..., num_agents, size) float32 -> normalised and clipped, same shape."""
        return torch.clamp((x - self.mean) / self.std, -self.clip, self.clip)

    def state_dict(self) -> dict:
        return {"count": self.count, "sum": torch.from_numpy(self.sum.copy()),
                "sum_sq": torch.from_numpy(self.sum_sq.copy())}

    def load_state_dict(self, state: dict) -> None:
        self.count = int(state["count"])
        self.sum = state["sum"].numpy().copy()
        self.sum_sq = state["sum_sq"].numpy().copy()
        if self.count:
            self.update(np.zeros((0, *self.sum.shape)))
