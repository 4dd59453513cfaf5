"""How the training copies act: uniform random actions during the warm-up, then the online
actors with Gaussian noise and a share of uniformly random actions, which may differ near the
box (``near_box.random_eps``) and far from it (``algo.random_eps``)."""

from __future__ import annotations

import numpy as np

from dualarm.training.config import TrainConfig
from dualarm.training.shaping import box_offset_columns, grip_to_box_distance


class Exploration:
    """The exploring policy of a run.

    Args:
        config: the run's settings.
        agent: the learner whose online actors explore.
        rng: the trainer's random stream (shared: one stream makes a run reproducible and
            resumable from its checkpoint).
    """

    def __init__(self, config: TrainConfig, agent, rng: np.random.Generator):
        self.config, self.agent, self.rng = config, agent, rng
        self.mask = agent.action_mask[:, 0].numpy()
        self.rel_columns = (box_offset_columns(config.task_config())
                            if config.near_box.random_eps is not None else None)

    def random_eps(self, obs: np.ndarray) -> np.ndarray | None:
        """The share of random exploring actions per copy and arm, (n, A), from observations
        (n, A, O): ``near_box.random_eps`` where the grip site is within ``near_box.radius`` m of
        its box, ``algo.random_eps`` farther away; None (the config's everywhere) without
        ``near_box.random_eps``."""
        near_box = self.config.near_box
        if near_box.random_eps is None:
            return None
        near = grip_to_box_distance(obs, self.rel_columns) <= near_box.radius
        return np.where(near, near_box.random_eps, self.config.algo.random_eps)

    def act(self, obs: np.ndarray, env_steps: int) -> np.ndarray:
        """Actions (n, A, U) in [-1, 1] for observations (n, A, O) after ``env_steps`` joint
        steps of the run: uniform before ``algo.warmup_steps``, the actors' after."""
        if env_steps < self.config.algo.warmup_steps:
            n, a = obs.shape[:2]
            return self.rng.uniform(-1.0, 1.0, (n, a, len(self.mask[0]))) * self.mask
        return self.agent.act(obs, self.rng, explore=True, random_eps=self.random_eps(obs))
