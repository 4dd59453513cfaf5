"""One round's transitions into the replay buffer: step by step, or each episode whole (what
hindsight relabelling needs), each also as its mirror image with ``replay.mirror``; and the
observations the normaliser is then updated with."""

from __future__ import annotations

import numpy as np

from dualarm.rl.her import HindsightSampler
from dualarm.rl.replay import ReplayBuffer
from dualarm.training.relabel import ReachRelabeller, TargetRelabeller


def hindsight_sampler(config, buffer: ReplayBuffer, task):
    """What batches are drawn through: ``buffer`` itself, or a ``HindsightSampler`` over it
    with the config's hindsight targets (``replay.her_share``) and recombination of the two
    arms' episodes (``replay.recombine_share``), the goals being the task's (reach or full)."""
    replay = config.replay
    if not (replay.her_share > 0 or replay.recombine_share > 0):
        return buffer
    achieved = relabel = recombine = None
    goals = ReachRelabeller if task.success_at == "reach" else TargetRelabeller
    relabeller = goals(task, task.observes_joint_angles)
    if replay.her_share > 0:
        achieved, relabel = relabeller.achieved, relabeller.relabel
    if replay.recombine_share > 0:         # the full task's (TrainConfig checks it)
        recombine = relabeller.recombine
    return HindsightSampler(buffer, achieved, relabel, replay.her_share, recombine,
                            replay.recombine_share)


class RoundStorage:
    """Stores the steps of one round of ``n`` episodes (``store``, run_round's ``on_step``)
    and then its whole episodes (``finish``).

    Args:
        buffer: the replay buffer.
        mirror: a ``TaskMirror`` (each step or episode is stored again as its mirror image), or None.
        whole: store each episode in one piece at the end of the round (hindsight needs the
            episode), else each step as it comes.
        n: episodes in the round (copies 0..n-1).
    """

    def __init__(self, buffer: ReplayBuffer, mirror, whole: bool, n: int):
        self.buffer, self.mirror, self.whole = buffer, mirror, whole
        self.episodes: list[list] = [[] for _ in range(n)]
        self.seen: list[np.ndarray] = []

    def store(self, obs: np.ndarray, actions: np.ndarray, step, live: np.ndarray) -> None:
        """One step of the copies ``live``: obs (N, A, O), actions (N, A, U), the step's
        ``VectorStep``."""
        reward = step.reward
        if not self.whole:
            self.buffer.add(obs[live], actions[live], reward[live], step.obs[live],
                            step.terminated[live])
            if self.mirror is not None:
                self.buffer.add(*self.mirror.episode(obs[live], actions[live], reward[live],
                                                     step.obs[live]), step.terminated[live])
        else:
            for i in live:
                self.episodes[i].append((obs[i], actions[i], reward[i], step.obs[i],
                                         step.terminated[i]))
        self.seen.append(step.obs[live])

    def finish(self, first_obs: np.ndarray) -> np.ndarray:
        """Store the round's whole episodes (if ``whole``) and return the observations the
        critics were shown this round, (k, A, O): the first ones ``first_obs`` (n, A, O), every
        next one, and their mirror images."""
        for steps in self.episodes:
            if steps:
                o, u, rew, o2, term = (np.stack(x) for x in zip(*steps))
                self.buffer.add_episode(o, u, rew, o2, bool(term[-1]))
                if self.mirror is not None:
                    self.buffer.add_episode(*self.mirror.episode(o, u, rew, o2), bool(term[-1]))
        seen = np.concatenate([first_obs, *self.seen])
        if self.mirror is not None:
            seen = np.concatenate([seen, self.mirror.obs(seen)])
        return seen
