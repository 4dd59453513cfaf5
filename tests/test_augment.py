"""More demonstrations than recordings: hand paths moved with their objects (dualarm.sim_demos.augment)."""

from __future__ import annotations

import numpy as np
import pytest

from dualarm.demos.scene import Scene
from dualarm.sim_demos.augment import augment, move_path, random_placement, segment_steps
from dualarm.sim_demos.replay import demonstration_path, follow_path


def test_move_path_follows_the_box_then_the_target_segment_by_segment():
    path = np.zeros((11, 2, 3))
    windows = np.array([[[0, 4], [4, 6], [6, 10]], [[0, 2], [2, 3], [3, 8]]], dtype=float)
    source = Scene(np.zeros((2, 3)), np.zeros((2, 3)))
    target = Scene(np.array([[0.1, 0.0, 0.004], [0.0, -0.2, 0.0]]),
                   np.array([[0.0, 0.3, 0.1], [0.0, 0.0, 0.2]]))
    moved = move_path(path, windows, source, target)
    np.testing.assert_allclose(moved[0], 0.0)                            # the start stays home
    np.testing.assert_allclose(moved[2, 0], [0.05, 0.0, 0.0])            # half way through reach
    np.testing.assert_allclose(moved[5, 0], [0.1, 0.0, 0.0])             # grasp: with the box, no height
    np.testing.assert_allclose(moved[8, 0], [0.05, 0.15, 0.05])          # half way through align
    np.testing.assert_allclose(moved[10, 0], target.targets[0])          # align ends at the target
    np.testing.assert_allclose(moved[2, 1], [0.0, -0.2, 0.0])            # each arm by its own labels
    np.testing.assert_allclose(moved[10, 1], target.targets[1])
    np.testing.assert_allclose(move_path(path + 1.0, windows, target, target), path + 1.0)


def test_segment_steps_puts_the_task_window_on_the_retimed_steps(shipped):
    env, demos, labels, scenes = shipped
    w = segment_steps(labels[demos[0].name], 40)
    assert w[:, 0, 0].min() == pytest.approx(0.0) and w[:, 2, 1].max() == pytest.approx(40.0)
    assert (np.diff(w.reshape(2, -1), axis=1) >= 0).all()                # in order, arm by arm


def test_recordings_moved_to_new_placements_succeed_and_unmoved_ones_do_not(shipped):
    """The moved recordings bring both boxes to targets that the person never saw (measured:
    98 of 100 placements at 40 steps), while the same recordings replayed unmoved at those
    placements miss (0 of 100): the success comes from moving the path with its objects."""
    env, demos, labels, scenes = shipped
    out = augment(env, demos, labels, scenes, episodes=10, seed=7)
    assert len(out.replays) == 10 and out.attempts <= 12
    assert all(r.success and r.done[-1] == 1.0 for r in out.replays)
    assert [r.name for r in out.replays[:8]] == [d.name for d in demos[:8]]   # taken in turn
    unmoved = 0
    for j, d in enumerate(demos[:5]):
        placement = random_placement(env, 7 + j)
        path, closed = demonstration_path(env, d, labels[d.name])
        unmoved += follow_path(env, d.name, path, closed, placement).success
    assert unmoved == 0
    again = augment(env, demos, labels, scenes, episodes=3, seed=7)     # seeded: the same episodes
    np.testing.assert_array_equal(again.replays[2].act, out.replays[2].act)


def test_the_replay_command_reports_the_yield_of_moved_recordings(capsys):
    from dualarm.cli.main import main

    assert main(["demos", "replay", "--moved", "4", "--seed", "2"]) == 0
    out = capsys.readouterr().out
    assert "moved to new placements: 4 of" in out and "yield" in out
    assert "demo_00    1 of 1" in out
    with pytest.raises(SystemExit) as exit_:
        main(["demos", "replay", "--moved", "4", "--seed", "-1"])
    assert exit_.value.code == 2 and "--seed: must be in 0.." in capsys.readouterr().err
