"""Hindsight relabelling of the arms' targets: rewards recomputed as the environment would."""

from __future__ import annotations

import dualarm  # noqa: F401

import numpy as np
import pytest

from dualarm.envs.baxter import BaxterBatch
from dualarm.envs.rules import HEAD_TERMS
from dualarm.training.relabel import TargetRelabeller
from dualarm.envs.config import TaskConfig
from dualarm.envs.expert import ScriptedExpert
from dualarm.rl.her import HindsightSampler
from dualarm.rl.replay import ReplayBuffer


def expert_episode(seed: int, task: TaskConfig, start_probs=None):
    """(obs, act, reward (T, 2), heads (T, 2, 3), next_obs, terminated) of one expert episode."""
    env = BaxterBatch(task, num_envs=1, start_probs=start_probs)
    expert = ScriptedExpert(task)
    obs = env.reset_env(0, seed)[0]
    rows = []
    for _ in range(task.max_episode_steps):
        a = expert(obs)
        step = env.step_all(a[None])
        terms = step.info["reward_terms"]
        heads = np.stack([sum(terms[t][0] for t in names) for names in HEAD_TERMS], -1)
        rows.append((obs, a, step.reward[0], heads, step.obs[0], step.terminated[0]))
        obs = step.obs[0]
        if step.terminated[0] or step.truncated[0]:
            break
    o, a, r, h, o2, term = (np.stack(x) for x in zip(*rows))
    return o, a, r, h, o2, bool(term[-1]), env


@pytest.mark.parametrize("split", [False, True])
def test_relabelling_with_the_real_targets_changes_nothing(split):
    task = TaskConfig()
    o, a, r, h, o2, term, env = expert_episode(3, task)
    assert term                                   # the expert succeeds: rc on the last step
    relabeller = TargetRelabeller(task, False)
    rew = h if split else r
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
    o, a, r, h, o2, term, env = expert_episode(5, task)
    relabeller = TargetRelabeller(task, False)
    held = np.flatnonzero([relabeller.goals.target_terms(o2[t:t + 1], o2[t:t + 1, :, -3:])[0].all()
                           and (relabeller.goals.target_terms(o2[t:t + 1], o2[t:t + 1, :, -3:])[0] < 0).all()
                           for t in range(len(o))])
    k = int(held[len(held) // 2])                 # a step at which both boxes are carried
    goals = relabeller.achieved(o2[k:k + 1])[0]
    batch = {"obs": o.copy(), "next_obs": o2.copy(), "rew": h.astype(np.float64).copy(),
             "done": np.zeros(len(o))}
    relabeller.relabel(batch, np.arange(len(o)), np.repeat(goals[None], len(o), 0))
    assert batch["done"][k] == 1.0 and batch["rew"][k, :, 2].tolist() == [task.coordinate_bonus] * 2
    np.testing.assert_allclose(batch["obs"][:, :, -3:], np.broadcast_to(goals, (len(o), 2, 3)))
    grip = o2[k, :, :3]
    np.testing.assert_allclose(batch["rew"][k, :, 0] - h[k, :, 0],
                               -np.linalg.norm(grip - goals, axis=1)
                               + np.linalg.norm(grip - env.target_pos[0], axis=1), atol=1e-9)


def test_future_goals_come_from_the_same_episode_later():
    task = TaskConfig()
    buffer = ReplayBuffer(1000, 2, 29, 4, 3)
    ends = []
    for seed in (1, 2):
        o, a, r, h, o2, term, env = expert_episode(seed, task)
        buffer.add_episode(o, a, h, o2, term)
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
    o, a, r, h, o2, term, env = expert_episode(2, task)
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


def _two_episodes(buffer_size: int = 100):
    """A buffer holding an episode of 6 steps that terminates and one of 5 cut by the time
    limit; obs[..., 0] is the step's storage row, rew that row's number + 1 (both agents)."""
    buffer = ReplayBuffer(buffer_size, 2, 4, 1)
    for length, terminated in ((6, True), (5, False)):
        start = len(buffer)
        rows = np.arange(start, start + length, dtype=np.float32)
        obs = np.zeros((length, 2, 4), np.float32)
        obs[..., 0] = rows[:, None]
        nxt = obs.copy()
        nxt[..., 0] += 0.5
        buffer.add_episode(obs, np.zeros((length, 2, 1)), np.repeat(rows[:, None] + 1, 2, 1),
                           nxt, terminated)
    return buffer


def test_n_step_returns_sum_the_rewards_of_the_episode_and_stop_at_its_end():
    gamma = 0.9
    buffer = _two_episodes()
    sampler = HindsightSampler(buffer, None, None, share=0.0, n_step=3, gamma=gamma)
    batch = {k: v.numpy() for k, v in sampler.sample(np.random.default_rng(1), 200).items()}
    ends = {0: (5, True), 1: (5, True), 2: (5, True), 3: (5, True), 4: (5, True), 5: (5, True),
            6: (10, False), 7: (10, False), 8: (10, False), 9: (10, False), 10: (10, False)}
    seen = set()
    for obs, rew, nxt, done, discount in zip(batch["obs"], batch["rew"], batch["next_obs"],
                                             batch["done"], batch["discount"]):
        t = int(obs[0, 0])
        last, terminates = ends[t]
        m = min(3, last - t + 1)
        seen.add(m)
        expected = sum(gamma ** k * (t + k + 1) for k in range(m))
        np.testing.assert_allclose(rew, [expected, expected], rtol=1e-6)
        assert nxt[0, 0] == t + m - 1 + 0.5                          # the state after m steps
        assert done == float(terminates and t + m - 1 == last)      # a time limit bootstraps
        np.testing.assert_allclose(discount, gamma ** m, rtol=1e-6)
    assert seen == {1, 2, 3}
    one = HindsightSampler(buffer, None, None, share=0.0, n_step=1, gamma=gamma)
    plain = one.sample(np.random.default_rng(1), 200)
    assert "discount" not in plain                                    # n = 1: Eq. 13 unchanged
    np.testing.assert_array_equal(plain["obs"].numpy(), batch["obs"])


def test_n_step_returns_relabel_every_step_for_the_rows_hindsight_goal():
    """Each of the m rewards of a relabelled row is the one its transition gets for that
    goal alone, and the sum stops at the step the goal is reached (the new end)."""
    task, gamma = TaskConfig(), 0.98
    relabeller = TargetRelabeller(task, False)
    buffer = ReplayBuffer(1000, 2, 29, 4, 3)
    for seed in (1, 2):
        o, a, r, h, o2, term, env = expert_episode(seed, task)
        buffer.add_episode(o, a, h, o2, term)
    sampler = HindsightSampler(buffer, relabeller.achieved, relabeller.relabel, share=1.0,
                               n_step=4, gamma=gamma)
    batch = {k: v.numpy() for k, v in sampler.sample(np.random.default_rng(3), 128).items()}
    data, stopped_early = buffer.data, 0
    for i in range(128):
        same = (data["obs"][:len(buffer), :, :-3] == batch["obs"][i, :, :-3]).all(axis=(1, 2))
        assert same.sum() == 1                                      # the target is the last 3
        t = int(np.flatnonzero(same)[0])
        goal = batch["obs"][i, :, -3:]
        total, m = np.zeros((2, 3)), 0
        for k in range(4):
            one = {key: data[key][t + k:t + k + 1].copy() for key in ("obs", "rew", "next_obs", "done")}
            relabeller.relabel(one, np.array([0]), goal[None])
            total += gamma ** k * one["rew"][0]
            m = k + 1
            if one["done"][0] or data["left"][t + k] == 0:
                break
        stopped_early += m < 4
        np.testing.assert_allclose(batch["rew"][i], total, rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(batch["discount"][i], gamma ** m, rtol=1e-6)
    assert stopped_early > 0


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
    coord = np.stack([ep[3][t][:, 2] for ep, t in sources])             # (3, 2) the env's bonus
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
        o, a, r, h, o2, term, env = expert_episode(seed, task)
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
    with pytest.raises(ValueError, match="recombine_share"):
        HindsightSampler(buffer, None, None, share=0.0, n_step=3, gamma=0.9,
                         recombine=relabeller.recombine, recombine_share=0.5)
