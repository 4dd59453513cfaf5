"""Dual-agent DDPG (paper Section 2.3): networks, replay, normalisation, noise and the update."""

from dualarm.rl.config import DADDPGConfig
from dualarm.rl.daddpg import DADDPG

__all__ = ["DADDPGConfig", "DADDPG"]
