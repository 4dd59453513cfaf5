"""Human-likeness of a policy against the demonstrations (dualarm.experiments.human_likeness)."""

from __future__ import annotations

import numpy as np

from dualarm.constraints.constraint_set import ConstraintSet, default_constraints_path
from dualarm.demos.formats import DEFAULT_DEMO_DIR
from dualarm.demos.loading import load_demo_dir
from dualarm.experiments.human_likeness import (PHASE_POINTS, DemoPostures, episode_phases,
                                                inside_share, posture_distance)


def test_the_phase_runs_through_each_stretch_of_one_sub_task():
    subtasks = np.array([[0, 0], [0, 0], [1, 0], [1, 1], [2, 1], [2, 2]])
    phase = episode_phases(subtasks)
    np.testing.assert_allclose(phase[:, 0], [0.5, 1.0, 0.5, 1.0, 0.5, 1.0])
    np.testing.assert_allclose(phase[:, 1], [1 / 3, 2 / 3, 1.0, 0.5, 1.0, 1.0])


def test_a_demonstration_is_at_distance_zero_from_itself_and_a_shift_is_measured():
    """Posture distance: 0 for the postures of a recording included in the set, at its own
    phases; a joint offset of 0.1 rad on all 7 joints of both arms reads as about 0.1 rad
    against that recording alone."""
    demos, labels = load_demo_dir(DEFAULT_DEMO_DIR)
    one = DemoPostures.from_recordings(demos[:1], labels)
    assert one.q.shape == (1, 2, 3, PHASE_POINTS, 7)
    # a synthetic episode sampled from the recording's own phase grid: sub-task k, its phase
    # samples in order
    steps = [(k, p) for k in range(3) for p in range(1, PHASE_POINTS)]
    q = np.concatenate([np.stack([one.q[0, arm, k, p] for k, p in steps]) for arm in range(2)], 1)
    subtasks = np.array([[k, k] for k, _ in steps])
    assert posture_distance(q, subtasks, one) < 1e-9
    assert abs(posture_distance(q + 0.1, subtasks, one) - 0.1) < 1e-9
    everyone = DemoPostures.from_recordings(demos, labels)
    assert posture_distance(q + 0.1, subtasks, everyone) <= 0.1 + 1e-9     # nearest of ten


def test_the_inside_share_counts_joint_steps_within_the_current_sub_tasks_range():
    cs = ConstraintSet.load(default_constraints_path("multi"))
    lo, hi = cs.bounds(0)
    middle = (lo + hi) / 2
    q = np.stack([middle, middle])
    assert inside_share(q, np.zeros((2, 2), int), cs) == 1.0
    q[1] = hi + 0.5                                               # every joint of step 2 outside
    assert inside_share(q, np.zeros((2, 2), int), cs) == 0.5


def test_the_report_gives_each_conditions_human_likeness_where_runs_have_a_policy(tmp_path):
    """A comparison directory whose run has a policy gets the Human-likeness table (policy
    episodes against the shipped demonstrations); run logs without checkpoints get none."""
    from dualarm.experiments.report import write_report
    from dualarm.training import TrainConfig, train

    tiny = {"num_envs": 2, "episodes": 4, "eval_every": 2, "eval_episodes": 2,
            "algo": {"hidden": [16, 16], "batch_size": 16, "warmup_steps": 0, "buffer_size": 2000},
            "task": {"max_episode_steps": 8}}
    train(TrainConfig.from_dict(tiny, base=TrainConfig.paper()), tmp_path / "cmp" / "runs" / "multi-seed0",
          progress=False)
    md = (write_report(tmp_path / "cmp", window=2).parent / "table.md").read_text()
    section = md[md.index("## Human-likeness"):md.index("## Runs")]
    assert "the demonstrations among themselves" in section
    row = next(line for line in section.splitlines() if line.startswith("| multi |"))
    inside, posture = (float(x) for x in row.strip("|").split("|")[2:4])
    assert 0.0 <= inside <= 1.0 and 0.0 < posture < 1.0
    (tmp_path / "cmp" / "runs" / "multi-seed0" / "checkpoints" / "best_policy.pt").unlink()
    (tmp_path / "cmp" / "runs" / "multi-seed0" / "checkpoints" / "latest.pt").unlink()
    md = (write_report(tmp_path / "cmp", window=2).parent / "table.md").read_text()
    assert "Human-likeness" not in md
