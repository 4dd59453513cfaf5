"""Replay transforms that rewrite stored steps of the Baxter task: hindsight goals (HER) and
recombined arm halves. The learner owns what it does with its data; the environment's goal
functions (``dualarm.envs.rules.TaskGoals``) say what was achieved and what a goal pays.

Batches are dicts of numpy arrays: obs, next_obs (n, 2, O) laid out as ``observation_layout``
says, act (n, 2, A), rew (n, 2), done (n,).
``dualarm.rl.her.HindsightSampler`` draws the rows and calls these.
"""

from __future__ import annotations

import numpy as np

from dualarm.envs.config import TaskConfig
from dualarm.envs.rules import TaskGoals


class TargetRelabeller:
    """Hindsight goals for the full task: each arm's target replaced by where its box was later.

    ``achieved(next_obs)`` gives the box positions (n, 2, 3); ``relabel`` rewrites a batch's
    rows for new targets: the target in both arms' observations, the distance term of an arm
    that holds its box, the coordination bonus and the end of the episode (``TaskGoals.
    target_terms``). The guide term and rg1/rg2 do not depend on the targets.
    """

    def __init__(self, config: TaskConfig, joint_angles: bool):
        if config.goal != "subtask":
            raise ValueError("hindsight targets follow the 'subtask' goal of the distance term")
        self.config = config
        self.goals = TaskGoals(config, joint_angles)
        self.achieved = self.goals.achieved_targets
        self.target = self.goals.layout["target_pos"]

    def relabel(self, batch: dict, rows: np.ndarray, targets: np.ndarray) -> None:
        """Rewrite ``batch`` rows ``rows`` (obs, next_obs, rew, done) for targets (len(rows), 2, 3)."""
        c, where = self.config, self.target
        nxt = batch["next_obs"][rows]
        old_distance, old_success = self.goals.target_terms(nxt, nxt[..., where])
        new_distance, new_success = self.goals.target_terms(nxt, targets)
        batch["obs"][rows, :, where] = targets
        batch["next_obs"][rows, :, where] = targets
        distance = new_distance - old_distance                         # (k, 2)
        batch["rew"][rows] += distance + c.coordinate_bonus * (new_success.astype(float)
                                                               - old_success)[:, None]
        batch["done"][rows] = new_success

    def recombine(self, batch: dict, rows: np.ndarray, partners: np.ndarray) -> None:
        """Give ``batch`` rows ``rows`` the right arm's half of rows ``partners`` (both (k,)):
        its observation, action, reward and next observation, next to the row's own left
        half. The arms and their boxes do not touch, so the two halves make a step the robot
        could have taken (counterfactual data augmentation of locally independent parts,
        Pitis et al. 2020); the only term that couples them, the coordination bonus of
        Eq. 18, and the end of the episode are computed again for the joined step.
        Transitions that ended by a physics failure (done without success) stay ended."""
        c, where = self.config, self.target
        _, stored = self.goals.target_terms(batch["next_obs"], batch["next_obs"][..., where])
        own, theirs = stored[rows], stored[partners]
        failed = (batch["done"][rows] > 0) & ~own | (batch["done"][partners] > 0) & ~theirs
        for key in ("obs", "act", "rew", "next_obs"):
            batch[key][rows, 1] = batch[key][partners, 1]
        nxt = batch["next_obs"][rows]
        _, joined = self.goals.target_terms(nxt, nxt[..., where])
        was = np.stack([own, theirs], axis=-1).astype(float)                # (k, 2)
        batch["rew"][rows] += c.coordinate_bonus * (joined[:, None] - was)
        batch["done"][rows] = joined | failed


class ReachRelabeller:
    """Hindsight goals for the reach task (``success_at="reach"``): each arm's box replaced by
    where its grip site was later in the episode, as HER does on FetchReach.

    ``achieved(next_obs)`` gives the grip sites (n, 2, 3); ``relabel`` rewrites a batch's rows
    as if the boxes had stood there: ``object_pos`` and ``object_rel_pos`` in both arms'
    observations, and the reward and the end of the episode (``TaskGoals.reach_reward``). rg1
    is paid at the step an arm comes within reach, where the environment pays it the first
    time only: the two differ for an arm that leaves and comes back. Whole rewards (n, 2) only.
    """

    def __init__(self, config: TaskConfig, joint_angles: bool):
        if config.success_at != "reach":
            raise ValueError("reach goals are relabelled for the reach task (success_at 'reach')")
        if config.reach_funnel > 0 or config.goal != "subtask":
            raise ValueError("reach relabelling needs the distance term's goal at the box itself "
                             "(goal 'subtask', reach_funnel 0)")
        self.config = config
        self.goals = TaskGoals(config, joint_angles)
        self.achieved = self.goals.achieved_boxes

    def relabel(self, batch: dict, rows: np.ndarray, goals: np.ndarray) -> None:
        """Rewrite ``batch`` rows ``rows`` (obs, next_obs, rew, done) for boxes at ``goals``
        (len(rows), 2, 3)."""
        L = self.goals.layout
        obs, nxt = batch["obs"][rows], batch["next_obs"][rows]
        old, _ = self.goals.reach_reward(obs, nxt, obs[..., L["object_pos"]], nxt[..., L["object_pos"]])
        new, success = self.goals.reach_reward(obs, nxt, goals, goals)
        for key, o in (("obs", obs), ("next_obs", nxt)):
            batch[key][rows, :, L["object_pos"]] = goals
            batch[key][rows, :, L["object_rel_pos"]] = goals - o[..., L["grip_pos"]]
        batch["rew"][rows] += new - old
        batch["done"][rows] = success & self.config.terminate_on_success
