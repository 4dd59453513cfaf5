"""A round's gradient updates, in one place: how many (``algo.updates_per_step`` per
environment step after warm-up, the fraction carried to the next round), what each batch holds
(replay rows drawn by the hindsight sampler, then ``algo.demo_batch_size`` demonstration rows)
and what is added to it before the update (the penalty weights and shaping, ``BatchShaping``)."""

from __future__ import annotations

import numpy as np
import torch

from dualarm.training.shaping import BatchShaping


#: Updates whose batches are drawn together (``GradientUpdates.batches``): the sampler's numpy
#: work costs per call, not per row (0.86 -> 0.36 ms per update with the recordings). The same
#: distribution as a draw per update; over 9 seeds of the reach test the two orders of draws
#: learned alike (docs/benchmarks.md, "A round's batches drawn together").
DRAWN_TOGETHER = 32


class GradientUpdates:
    """The trainer's updates of ``agent``.

    Args:
        config: the run's ``TrainConfig``.
        agent: the ``DADDPG`` learner.
        buffer: the replay buffer (its length decides whether learning has started).
        sampler: draws the replay rows (``dualarm.rl.her.HindsightSampler`` or the buffer).
        demos: the demonstration buffer, or None.
        rng: the trainer's random stream (shared: one stream makes a run reproducible).

    Attributes:
        owed: updates earned but not yet made (a fraction below 1; kept in checkpoints).
        shaping: the ``BatchShaping`` applied to every batch.
    """

    def __init__(self, config, agent, buffer, sampler, demos, rng: np.random.Generator):
        self.algo, self.agent, self.buffer = config.algo, agent, buffer
        self.sampler, self.demos, self.rng = sampler, demos, rng
        self.shaping = BatchShaping(config, agent)
        self.owed = 0.0

    def run(self, env_steps: int, round_steps: int) -> list[dict]:
        """The round's share of updates (none during warm-up); their losses, one dict each.

        Raises:
            NonFiniteLoss: a loss became NaN or infinite (the agent is left as before it).
        """
        a = self.algo
        if env_steps < a.warmup_steps or len(self.buffer) < a.batch_size:
            return []
        self.owed += a.updates_per_step * round_steps
        count = int(self.owed)
        self.owed -= count
        demo_rows = a.demo_batch_size if self.demos is not None else 0
        losses = []
        for first in range(0, count, DRAWN_TOGETHER):
            for batch in self.batches(min(DRAWN_TOGETHER, count - first), demo_rows):
                losses.append(self.agent.update(batch, demo_rows))
        return losses

    def batches(self, k: int, demo_rows: int) -> list[dict[str, torch.Tensor]]:
        """``k`` update batches drawn in one pass: each ``algo.batch_size`` replay rows, then
        ``demo_rows`` demonstration rows, shaping applied. One draw of k x B rows is the same
        distribution as k draws of B (the replay does not change between a round's updates)
        at a fraction of the per-call cost of the sampler's numpy work."""
        b = self.algo.batch_size
        drawn = self.sampler.sample(self.rng, k * b)
        if demo_rows:
            demos = self.demos.sample(self.rng, k * demo_rows)
            drawn = {key: torch.cat([v.view(k, b, *v.shape[1:]),
                                     demos[key].view(k, demo_rows, *v.shape[1:])], 1).flatten(0, 1)
                     for key, v in drawn.items()}
        self.shaping.apply(drawn)
        rows = b + demo_rows
        return [{key: v[i * rows:(i + 1) * rows] for key, v in drawn.items()} for i in range(k)]
