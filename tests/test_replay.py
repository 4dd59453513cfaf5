"""Human recordings replayed in the simulator at their own scenes (dualarm.sim_demos.replay)."""

from __future__ import annotations

import numpy as np
import pytest

from dualarm.cli.main import main
from dualarm.demos.formats import DEFAULT_DEMO_DIR
from dualarm.demos.loading import load_demo_dir
from dualarm.demos.scene import Scene, demo_scenes
from dualarm.envs import make_core
from dualarm.sim_demos.replay import DEFAULT_STEPS, replay_demonstration, retime, task_window


@pytest.fixture(scope="module")
def shipped():
    env = make_core()
    demos, labels = load_demo_dir(DEFAULT_DEMO_DIR, with_grip=True)
    scenes = demo_scenes(DEFAULT_DEMO_DIR, [d.name for d in demos], env.config.workspace())
    yield env, demos, labels, scenes
    env.close()


def test_a_placement_puts_the_boxes_and_targets_where_it_says():
    env = make_core()
    boxes = np.array([[0.62, 0.2, 0.5], [0.7, -0.15, 0.5]])      # z: the boxes rest on the table
    targets = np.array([[0.68, 0.09, 0.95], [0.68, -0.11, 0.95]])
    env.reset(placement=Scene(boxes, targets))
    np.testing.assert_allclose(env.box_start[:, :2], boxes[:, :2])
    assert np.allclose(env.box_start[:, 2], env.box_rest_z)
    np.testing.assert_allclose(env.targets, targets)
    env.reset(seed=3)
    first = env.box_start.copy()
    env.reset(seed=3)                                            # random placements unchanged
    np.testing.assert_array_equal(env.box_start, first)
    env.close()


def test_retime_samples_the_window_evenly_and_keeps_its_ends():
    time = np.linspace(0.0, 4.0, 401)
    values = np.stack([time, 2 * time], axis=1)
    out = retime(time, values, 1.0, 3.0, 4)
    np.testing.assert_allclose(out[:, 0], [1.0, 1.5, 2.0, 2.5, 3.0])
    np.testing.assert_allclose(out[:, 1], 2 * out[:, 0])


def test_the_shipped_recordings_replay_to_success_at_their_own_scenes(shipped):
    """Mapped, retimed to the learner's pace and followed in cartesian control, at least 8 of
    the 10 shipped recordings bring both boxes to their targets (measured: 10 of 10 at 40
    steps, 9-10 of 10 from 30 to 50, 3 at 25), and each replay is an episode of the task as the
    learner stores it, paid by the environment (rc on the success step)."""
    env, demos, labels, scenes = shipped
    replays = [replay_demonstration(env, d, labels[d.name], scenes[d.name]) for d in demos]
    assert sum(r.success for r in replays) >= 8, [(r.name, r.why) for r in replays]
    for r in replays:
        assert r.retimed_steps == DEFAULT_STEPS and r.steps <= env.config.max_episode_steps
        assert r.obs.shape == r.next_obs.shape == (r.steps, 2, env.obs_size)
        assert r.act.shape == (r.steps, 2, env.action_size) and np.abs(r.act).max() <= 1.0
        np.testing.assert_array_equal(r.obs[1:], r.next_obs[:-1])
        if r.success:
            assert r.done[-1] == 1.0 and r.done[:-1].sum() == 0
            assert (r.rew[-1] >= env.config.coordinate_bonus - 10).all()
    start, end = task_window(labels[demos[0].name])
    assert 2.0 < end - start < 6.0                               # a person's few seconds


def test_a_recording_replayed_at_another_scene_misses_its_boxes(shipped):
    """The replay follows the recorded hands, not the boxes: moved 8 cm, the boxes are missed
    (so a success above is the recording's, at its own scene)."""
    env, demos, labels, scenes = shipped
    d = demos[0]
    own = scenes[d.name]
    moved = Scene(own.boxes + np.array([[-0.08, 0.0, 0.0], [-0.08, 0.0, 0.0]]), own.targets)
    r = replay_demonstration(env, d, labels[d.name], moved)
    assert not r.success and "ended in reach" in r.why


def test_the_replay_command_prints_each_recording_and_the_count(capsys):
    assert main(["demos", "replay", "--steps", "40"]) == 0
    out = capsys.readouterr().out
    assert "recordings replay to success at their own scene" in out and "demo_09" in out
    assert main(["demos", "replay", "--steps", "51"]) == 2
    assert "at most the episode's 50 steps" in capsys.readouterr().err
