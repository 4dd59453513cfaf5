"""Training start states: an arm may begin an episode at its box (grasp) or holding it (align)."""

from __future__ import annotations

import dualarm  # noqa: F401  (headless GL before mujoco loads)

import numpy as np
import pytest

from dualarm.envs.baxter import BaxterBatch
from dualarm.envs.config import TaskConfig
from dualarm.envs.expert import ScriptedExpert
from dualarm.envs.starts import StartDistribution
from dualarm.training.config import TrainConfig
from dualarm.training.vector import make_vector_env


@pytest.mark.parametrize("control", ["cartesian", "joint"])
def test_held_start_grasps_the_box_and_keeps_it(control):
    env = BaxterBatch(TaskConfig(control=control), num_envs=1, starts=StartDistribution((0.0, 0.0, 1.0)))
    grip = np.zeros((1, 2, env.action_size))
    grip[..., -1] = 1.0                              # keep the fingers closed, do not move
    for seed in range(8):
        obs, info = env.reset_env(0, seed)
        assert list(info["subtask"]) == [2, 2]
        assert info["grasped"].all()
        for _ in range(10):
            step = env.step_all(grip)
            assert step.info["grasped"][0].all()     # held, not dropped
            assert step.info["reward_terms"]["goal"][0].sum() == 0   # rg1, rg2 not paid for it
            if step.terminated[0] or step.truncated[0]:
                break


def test_held_boxes_lie_between_their_start_and_target_and_above_the_table():
    env = BaxterBatch(TaskConfig(), num_envs=1, starts=StartDistribution((0.0, 0.0, 1.0)))
    plain = BaxterBatch(TaskConfig(), num_envs=1)
    lifted = env.box_rest_z + env.config.lift_height
    for seed in range(10):
        env.reset_env(0, seed)
        plain.reset_env(0, seed)
        # the seed places boxes and targets as the normal reset does
        np.testing.assert_array_equal(env.box_start_pos[0], plain.box_start_pos[0])
        np.testing.assert_array_equal(env.target_pos[0], plain.target_pos[0])
        box = env._qpos[0, :, 9:12]
        start, target = env.box_start_pos[0], env.target_pos[0]
        assert (box[:, 2] > lifted).all()
        for arm in range(2):   # horizontally on the segment from start to target (within 1 cm)
            d, s = target[arm, :2] - start[arm, :2], box[arm, :2] - start[arm, :2]
            f = np.clip(s @ d / (d @ d), 0, 1)
            assert np.linalg.norm(s - f * d) < 0.01


def test_grasp_start_puts_the_open_gripper_at_the_resting_box():
    env = BaxterBatch(TaskConfig(), num_envs=1, starts=StartDistribution((0.0, 1.0, 0.0)))
    for seed in range(5):
        obs, info = env.reset_env(0, seed)
        assert list(info["subtask"]) == [1, 1] and not info["grasped"].any()
        rel = obs[:, env.layout["object_rel_pos"]]
        assert np.linalg.norm(rel, axis=1).max() < env.config.reach_threshold
        np.testing.assert_allclose(env._qpos[0, :, 9:12], env.box_start_pos[0], atol=2e-3)


def test_scripted_expert_finishes_from_mixed_starts():
    """The later starts are states the task reaches anyway: the expert carries on from them."""
    task = TaskConfig()
    env = BaxterBatch(task, num_envs=1, starts=StartDistribution((0.4, 0.3, 0.3)))
    expert = ScriptedExpert(task)
    starts, wins = [], 0
    for seed in range(20):
        obs, info = env.reset_env(0, seed)
        starts.extend(info["subtask"])
        for _ in range(task.max_episode_steps):
            step = env.step_all(expert(obs)[None])
            obs = step.obs[0]
            if step.terminated[0] or step.truncated[0]:
                break
        wins += bool(step.info["is_success"][0])
    assert set(starts) == {0, 1, 2}
    assert wins >= 18


@pytest.mark.parametrize("bad", [(0.5, 0.5), (0.5, 0.6, 0.0), (-0.1, 0.6, 0.5), (np.nan, 0.5, 0.5)])
def test_start_probabilities_are_checked(bad):
    with pytest.raises(ValueError, match="start probabilities"):
        StartDistribution(bad)
    with pytest.raises(Exception, match="starts: probs"):
        TrainConfig.from_dict({"starts": {"probs": list(bad)}})


def test_only_training_copies_use_the_start_distribution():
    config = TrainConfig.paper().with_(condition="none", starts={"probs": (0.0, 0.0, 1.0)})
    assert TrainConfig.from_dict(config.to_dict()) == config
    train = make_vector_env(config, 1, training=True)
    evaluation = make_vector_env(config, 1)
    assert (train.batch.reset_env(0, 1)[1]["subtask"] == 2).all()
    assert (evaluation.batch.reset_env(0, 1)[1]["subtask"] == 0).all()


def test_approach_starts_put_the_open_gripper_between_home_and_above_the_box():
    """With approach starts, reach starts spread along the way to the box (evaluation copies
    and arms at later sub-tasks are unchanged)."""
    from dualarm.envs.baxter import APPROACH_HEIGHT

    task = TaskConfig()
    home = BaxterBatch(task, num_envs=1)
    spread = BaxterBatch(task, num_envs=1, starts=StartDistribution(approach=True))
    fractions = []
    for seed in range(12):
        o_home = home.reset_env(0, seed)[0]
        o = spread.reset_env(0, seed)[0]
        assert (spread.start_kind[0] == 0).all()
        start, box = o_home[:, :3], o[:, 3:6]
        above = box + [0.0, 0.0, APPROACH_HEIGHT]
        for arm in range(2):
            way = above[arm] - start[arm]
            u = float((o[arm, :3] - start[arm]) @ way / (way @ way))
            off_line = np.linalg.norm(o[arm, :3] - (start[arm] + u * way))
            assert -0.01 <= u <= 1.01 and off_line < 0.01, (seed, arm, u, off_line)
            fractions.append(u)
        from dualarm.envs.rules import closed_gap, finger_gap
        assert (finger_gap(o[:, 9:11]) > closed_gap(task) + 0.01).all()     # fingers open
    assert min(fractions) < 0.3 and max(fractions) > 0.7          # spread along the way
    with pytest.raises(Exception, match="approach moves the start states"):
        TrainConfig.paper().with_(starts={"approach": True})

