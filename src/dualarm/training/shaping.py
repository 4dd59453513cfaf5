"""What the trainer adds to every update's batch beyond the environment's rewards: the action
penalty's weight by region (``near_box.far_action_l2``) and potential-based shaping
(``shaping.approach``, ``shaping.carry``; Ng et al. 1999), both read from the raw observations."""

from __future__ import annotations

import torch

from dualarm.envs.rules import observation_layout
from dualarm.training.config import TrainConfig


def box_offset_columns(task) -> slice:
    """The columns (3,) of each arm's box-minus-grip offset in the observations of ``task``
    (a ``TaskConfig``)."""
    return observation_layout(task.observes_joint_angles)["object_rel_pos"]


def grip_to_box_distance(obs, rel_columns: slice):
    """Each arm's grip-to-box distance (m), (..., A), from raw observations (..., A, O),
    numpy or torch; ``rel_columns`` from ``box_offset_columns``."""
    return (obs[..., rel_columns] ** 2).sum(-1) ** 0.5


def approach_potential(obs, rel_columns: slice, k: float):
    """``shaping.approach``'s potential phi(s) = -k x each arm's grip-to-box distance (m),
    (..., A), from raw observations (..., A, O), numpy or torch. In the learner's reward units."""
    return -k * grip_to_box_distance(obs, rel_columns)


def shaping_potential(config: TrainConfig):
    """The run's potential phi(obs) -> (..., A) for raw observations (..., A, O), numpy or
    torch, in the learner's reward units: -``shaping.approach`` x the grip-to-box distance
    - ``shaping.carry`` x the box-to-target distance (m). None when both are 0."""
    approach, carry = config.shaping.approach, config.shaping.carry
    if approach == 0 and carry == 0:
        return None
    task = config.task_config()
    layout = observation_layout(task.observes_joint_angles)
    rel, box, target = layout["object_rel_pos"], layout["object_pos"], layout["target_pos"]

    def phi(obs):
        value = approach_potential(obs, rel, approach)
        if carry > 0:
            value = value - carry * ((obs[..., target] - obs[..., box]) ** 2).sum(-1) ** 0.5
        return value
    return phi


class BatchShaping:
    """Adds the run's ``penalty_weight`` and ``shaping`` columns to a batch (``apply``).

    Args:
        config: the run's settings.
        agent: the learner (its ``action_l2``, which a schedule may change, is the near weight).
    """

    def __init__(self, config: TrainConfig, agent):
        self.config, self.agent = config, agent
        self.potential = shaping_potential(config)
        self.rel_columns = (box_offset_columns(config.task_config())
                            if config.near_box.far_action_l2 is not None else None)

    def penalty_weight(self, obs: torch.Tensor) -> torch.Tensor:
        """The action penalty's weight per sample and arm, (B, A), from raw observations
        (B, A, O): ``near_box.far_action_l2`` where the grip site is more than ``near_box.radius`` m
        from its box, the learner's ``action_l2`` within it."""
        near_box = self.config.near_box
        far = grip_to_box_distance(obs, self.rel_columns) > near_box.radius
        return torch.where(far, near_box.far_action_l2, self.agent.action_l2)

    def shaping(self, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        """The potential-based shaping term per sample and arm, (B, A), in the learner's
        reward units: gamma * phi(s') * (1 - done) - phi(s), phi from ``shaping_potential``
        on the raw observations (B, A, O) (a success ends the episode with phi = 0, so the
        shaped return differs from the paper's by -phi(s0) only)."""
        gamma = self.config.algo.gamma
        phi, phi2 = self.potential(batch["obs"]), self.potential(batch["next_obs"])  # (B, A)
        return gamma * (1.0 - batch["done"]).unsqueeze(-1) * phi2 - phi

    def apply(self, batch: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """``batch`` with ``penalty_weight`` (B, A) and ``shaping`` (B, A) added where the run
        uses them (in place; returned for convenience)."""
        if self.rel_columns is not None:
            batch["penalty_weight"] = self.penalty_weight(batch["obs"])
        if self.potential is not None:
            batch["shaping"] = self.shaping(batch)
        return batch
