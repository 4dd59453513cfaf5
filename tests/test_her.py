"""Hindsight relabelling of the arms' targets: rewards recomputed as the environment would."""

from __future__ import annotations

import dualarm  # noqa: F401

import numpy as np
import pytest

from dualarm.envs.baxter import BaxterBatch
from dualarm.training.relabel import TargetRelabeller
from dualarm.envs.config import TaskConfig
from dualarm.envs.expert import ScriptedExpert
from dualarm.rl.her import HindsightSampler
from dualarm.rl.replay import ReplayBuffer


def expert_episode(seed: int, task: TaskConfig):
    """(obs, act, reward (T, 2), its coordination bonus term (T, 2), next_obs, terminated, env)
    of one expert episode."""
    env = BaxterBatch(task, num_envs=1)
    expert = ScriptedExpert(task)
    obs = env.reset_env(0, seed)[0]
    rows = []
    for _ in range(task.max_episode_steps):
        a = expert(obs)
        step = env.step_all(a[None])
        coord = step.info["reward_terms"]["coordinate"][0]
        rows.append((obs, a, step.reward[0], coord, step.obs[0], step.terminated[0]))
        obs = step.obs[0]
        if step.terminated[0] or step.truncated[0]:
            break
    o, a, r, c, o2, term = (np.stack(x) for x in zip(*rows))
    return o, a, r, c, o2, bool(term[-1]), env


def test_relabelling_with_the_real_targets_changes_nothing():
    task = TaskConfig()
    o, a, r, _, o2, term, env = expert_episode(3, task)
    assert term                                   # the expert succeeds: rc on the last step
    relabeller = TargetRelabeller(task, False)
    rew = r
    batch = {"obs": o.copy(), "next_obs": o2.copy(), "rew": rew.astype(np.float64).copy(),
             "done": np.zeros(len(o))}
    batch["done"][-1] = 1.0
    rows = np.arange(len(o))
    relabeller.relabel(batch, rows, np.repeat(env.target_pos[0][None], len(o), 0))
    np.testing.assert_allclose(batch["rew"], rew, atol=1e-9)
    np.testing.assert_array_equal(batch["done"], (np.arange(len(o)) == len(o) - 1))


def test_relabelling_with_where_the_boxes_went_pays_the_coordination_bonus():
    """Boxes held and carried, targets moved to where they were at step k: the bonus and the
    end of the episode move to step k, and the held arms' distance is to the new targets."""
    task = TaskConfig()
    o, a, r, _, o2, term, env = expert_episode(5, task)
    relabeller = TargetRelabeller(task, False)
    held = np.flatnonzero([relabeller.goals.target_terms(o2[t:t + 1], o2[t:t + 1, :, -3:])[0].all()
                           and (relabeller.goals.target_terms(o2[t:t + 1], o2[t:t + 1, :, -3:])[0] < 0).all()
                           for t in range(len(o))])
    k = int(held[len(held) // 2])                 # a step at which both boxes are carried
    goals = relabeller.achieved(o2[k:k + 1])[0]
    batch = {"obs": o.copy(), "next_obs": o2.copy(), "rew": r.astype(np.float64).copy(),
             "done": np.zeros(len(o))}
    relabeller.relabel(batch, np.arange(len(o)), np.repeat(goals[None], len(o), 0))
    assert batch["done"][k] == 1.0
    np.testing.assert_allclose(batch["obs"][:, :, -3:], np.broadcast_to(goals, (len(o), 2, 3)))
    grip = o2[k, :, :3]
    np.testing.assert_allclose(batch["rew"][k] - r[k], task.coordinate_bonus
                               - np.linalg.norm(grip - goals, axis=1)
                               + np.linalg.norm(grip - env.target_pos[0], axis=1), atol=1e-6)


def test_future_goals_come_from_the_same_episode_later():
    task = TaskConfig()
    buffer = ReplayBuffer(1000, 2, 29, 4)
    ends = []
    for seed in (1, 2):
        o, a, r, _, o2, term, env = expert_episode(seed, task)
        buffer.add_episode(o, a, r, o2, term)
        ends.append(len(buffer))
    seen = []

    def relabel(batch, rows, goals):
        seen.append((batch["obs"][rows], goals))

    sampler = HindsightSampler(buffer, lambda nxt: nxt[..., 3:6], relabel, share=1.0)
    rng = np.random.default_rng(0)
    for _ in range(5):
        sampler.sample(rng, 64)
    obs_rows, goals = seen[0][0], seen[0][1]
    # every goal is a box position of a later-or-same transition of the same episode
    nxt = buffer.data["next_obs"][:len(buffer)]
    for row_obs, goal in zip(obs_rows, goals):
        t = int(np.flatnonzero((buffer.data["obs"][:len(buffer)] == row_obs).all(axis=(1, 2)))[0])
        episode_end = next(e for e in ends if t < e)
        later = [u for u in range(t, episode_end) if np.array_equal(nxt[u, :, 3:6], goal)]
        assert later, f"goal of transition {t} is not from its own episode's future"


def test_reach_relabelling_with_the_real_boxes_changes_nothing_and_with_the_grips_pays_rc():
    """The reach task: relabelling with the boxes where they are leaves rewards and ends as the
    environment gave them; with the boxes moved to where the grip sites were at step k, both
    arms are within reach there: rc is paid and the episode ends at k."""
    from dualarm.training.relabel import ReachRelabeller

    task = TaskConfig(success_at="reach", max_episode_steps=30)
    o, a, r, _, o2, term, env = expert_episode(2, task)
    assert term
    relabeller = ReachRelabeller(task, False)
    batch = {"obs": o.copy(), "next_obs": o2.copy(), "rew": r.astype(np.float64).copy(),
             "done": (np.arange(len(o)) == len(o) - 1).astype(float)}
    rows = np.arange(len(o))
    relabeller.relabel(batch, rows, o2[:, :, 3:6])          # object_pos: where the boxes are
    np.testing.assert_allclose(batch["rew"], r, atol=1e-6)
    np.testing.assert_array_equal(batch["done"], np.arange(len(o)) == len(o) - 1)

    k = len(o) // 2
    grips = relabeller.achieved(o2[k:k + 1])[0]
    batch = {"obs": o.copy(), "next_obs": o2.copy(), "rew": r.astype(np.float64).copy(),
             "done": np.zeros(len(o))}
    relabeller.relabel(batch, rows, np.repeat(grips[None], len(o), 0))
    assert batch["done"][k] == 1.0 and (batch["rew"][k] > task.coordinate_bonus - 1).all()
    np.testing.assert_allclose(batch["obs"][:, :, 3:6], np.broadcast_to(grips, (len(o), 2, 3)))
    np.testing.assert_allclose(batch["next_obs"][:, :, 6:9],
                               grips[None] - o2[:, :, :3], atol=1e-12)      # rel = box - grip
    with pytest.raises(ValueError, match="reach task"):
        ReachRelabeller(TaskConfig(), False)


def test_recombined_rows_join_two_steps_and_pay_the_coordination_bonus_only_when_both_align():
    """recombine gives a row the right arm's half of another: the halves are copied whole,
    each arm keeps the reward the environment paid its own half less the coordination bonus
    of the step it came from, plus the bonus of the joined step (both boxes aligned), which
    also ends the episode."""
    task = TaskConfig()
    x = expert_episode(3, task)
    y = expert_episode(5, task)
    assert x[5] and y[5]                             # both succeed on their last step
    rc = task.coordinate_bonus
    mid = len(x[0]) // 2
    sources = [(x, -1), (x, mid), (y, -1)]           # success, not yet, success
    batch = {k: np.stack([ep[i][t] for ep, t in sources]).astype(np.float64)
             for i, k in ((0, "obs"), (1, "act"), (2, "rew"), (4, "next_obs"))}
    batch["done"] = np.array([1.0, 0.0, 1.0])
    coord = np.stack([ep[3][t] for ep, t in sources])                   # (3, 2) the env's bonus
    assert coord[:, 0].tolist() == [rc, 0.0, rc]
    original = {k: v.copy() for k, v in batch.items()}
    rows, partners = np.array([0, 1, 2]), np.array([2, 2, 1])
    TargetRelabeller(task, False).recombine(batch, rows, partners)
    for key in ("obs", "act", "next_obs"):
        np.testing.assert_array_equal(batch[key][:, 0], original[key][rows, 0])
        np.testing.assert_array_equal(batch[key][:, 1], original[key][partners, 1])
    joined = np.array([True, False, False])          # x's last + y's last; x mid + y last; y last + x mid
    np.testing.assert_array_equal(batch["done"], joined)
    own_terms = np.stack([original["rew"][rows, 0] - coord[rows, 0],
                          original["rew"][partners, 1] - coord[partners, 1]], -1)
    np.testing.assert_allclose(batch["rew"], own_terms + rc * joined[:, None], atol=1e-9)


def test_the_sampler_recombines_its_share_of_rows_and_leaves_the_draws_alone_without_it():
    task = TaskConfig()
    buffer = ReplayBuffer(1000, 2, 29, 4)
    for seed in (1, 2):
        o, a, r, _, o2, term, env = expert_episode(seed, task)
        buffer.add_episode(o, a, r, o2, term)
    relabeller = TargetRelabeller(task, False)
    plain = HindsightSampler(buffer, relabeller.achieved, relabeller.relabel, share=0.8)
    zero = HindsightSampler(buffer, relabeller.achieved, relabeller.relabel, share=0.8,
                            recombine=relabeller.recombine, recombine_share=0.0)
    half = HindsightSampler(buffer, relabeller.achieved, relabeller.relabel, share=0.8,
                            recombine=relabeller.recombine, recombine_share=0.5)
    a, b = plain.sample(np.random.default_rng(0), 512), zero.sample(np.random.default_rng(0), 512)
    for key in a:
        assert np.array_equal(a[key].numpy(), b[key].numpy()), key
    c = half.sample(np.random.default_rng(0), 512)
    # a joined row's halves come from two different steps: their step counters differ
    stored = buffer.data["obs"][:len(buffer)]
    left_rows = [np.flatnonzero((stored[:, 0, :3] == row[0, :3]).all(-1)) for row in c["obs"].numpy()]
    right_rows = [np.flatnonzero((stored[:, 1, :3] == row[1, :3]).all(-1)) for row in c["obs"].numpy()]
    apart = np.mean([not set(l) & set(r) for l, r in zip(left_rows, right_rows)])
    assert 0.3 < apart < 0.55, apart                 # about half the rows (a few join a row with itself)
    with pytest.raises(ValueError, match="recombine_share"):
        HindsightSampler(buffer, relabeller.achieved, relabeller.relabel, recombine_share=0.5)
