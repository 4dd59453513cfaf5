"""Per-arm outcomes of a policy's episodes (`dualarm.training.outcomes`): each scripted
behaviour lands in the class that names it."""

import numpy as np
import pytest

from dualarm.envs.config import TaskConfig
from dualarm.envs.expert import ScriptedExpert
from dualarm.envs.starts import StartDistribution
from dualarm.task import SUBTASKS
from dualarm.training.outcomes import OUTCOMES, link_outcomes
from dualarm.training.vector import BaxterVector

TASK = TaskConfig(condition="none")
EPISODES = 4


def outcomes(policy, start="reach", episodes=EPISODES, task=TASK):
    """Report of ``policy`` (obs (2, O), step -> action (2, 4)) from ``start``."""
    k = SUBTASKS.index(start)
    vec = BaxterVector(task, None, episodes, StartDistribution(tuple(float(i == k) for i in range(3))))
    steps = {"n": 0}

    def act(obs):
        steps["n"] += 1
        return np.stack([policy(o, steps["n"]) for o in obs])

    try:
        return link_outcomes(act, vec, task, episodes)
    finally:
        vec.close()


def only(report, outcome):
    """Every episode of both arms has ``outcome``."""
    assert report.counts.sum(axis=1).tolist() == [report.episodes] * 2
    k = OUTCOMES.index(outcome)
    assert report.counts[:, k].tolist() == [report.episodes] * 2, report.table()


def command(dx=0.0, dz=0.0, grip=0.0):
    a = np.zeros((2, 4))
    a[:, 0], a[:, 2], a[:, 3] = dx, dz, grip
    return a


def test_an_arm_that_does_not_move_is_still():
    only(outcomes(lambda o, t: command(grip=-1.0)), "still")


def test_an_arm_that_moves_away_has_moved_without_reaching():
    only(outcomes(lambda o, t: command(dz=1.0, grip=-1.0)), "moved, not reached")


def toward_above(obs, height, grip):
    """Both arms move to ``height`` m above their boxes' centres, grip command ``grip``."""
    from dualarm.envs.rules import observation_layout

    rel = obs[:, observation_layout(TASK.observes_joint_angles)["object_rel_pos"]] + [0, 0, height]
    a = np.zeros((2, 4))
    a[:, :3], a[:, 3] = np.clip(rel / 0.05, -1.0, 1.0), grip
    return a


def test_an_arm_that_closes_its_hand_near_the_box_has_closed_without_reaching():
    """Closed 3 cm above the box (the reach needs 2 cm): closed, not reached; the closest
    approach of each unreached arm is kept."""
    report = outcomes(lambda o, t: toward_above(o, 0.03, 1.0))
    only(report, "closed, not reached")
    assert all(0.02 < d < 0.05 for arm in report.closest_unreached for d in arm)
    assert "not reached: closest, cm" in report.table()


def test_a_closed_hand_that_never_comes_near_the_box_has_moved_without_reaching():
    """Fingers closed while flying up and away: the approach failed, not the grip."""
    report = outcomes(lambda o, t: command(dz=1.0, grip=1.0))
    only(report, "moved, not reached")
    assert all(d > 0.15 for arm in report.closest_unreached for d in arm)


def test_open_fingers_at_the_box_are_reached_not_closed():
    only(outcomes(lambda o, t: command(grip=-1.0), start="grasp"), "reached, not closed")


def test_half_closed_fingers_that_never_lift_are_closed_not_lifted():
    only(outcomes(lambda o, t: command(grip=0.0), start="grasp"), "closed, not lifted")


def test_a_grip_that_drifts_while_closing_closes_off_the_box():
    only(outcomes(lambda o, t: command(dx=0.6, grip=1.0), start="grasp"), "closed off the box")


def test_closing_then_lifting_holds_the_box_away_from_its_target():
    """Fingers closed for 4 steps, then straight up: held (measured: grasped at step 6),
    and each held box's distance from its target is kept: it went up, not toward it."""
    report = outcomes(lambda o, t: command(dz=0.5 if t > 4 else 0.0, grip=1.0), start="grasp")
    only(report, "held, not at target")
    assert [len(d) for d in report.held_away] == [EPISODES, EPISODES]
    assert all(d > TASK.align_threshold for arm in report.held_away for d in arm)
    assert "held: from target, cm" in report.table()


def test_a_carry_that_stops_short_is_held_just_off_the_target():
    """From holding the box, moved to 5 cm beside the target and kept there: held, with
    every box about 5 cm from its target (the carry fell short, not the grasp)."""
    from dualarm.envs.rules import observation_layout

    layout = observation_layout(TASK.observes_joint_angles)

    def short(obs, t):
        aim = obs[:, layout["target_pos"]] - obs[:, layout["object_pos"]] - [0.05, 0.0, 0.0]
        a = np.zeros((2, 4))
        a[:, :3], a[:, 3] = np.clip(aim / 0.05, -1.0, 1.0), 1.0
        return a

    report = outcomes(short, start="align")
    only(report, "held, not at target")
    assert all(0.035 < d < 0.07 for arm in report.held_away for d in arm), report.held_away


def test_opening_the_hand_drops_a_held_box():
    only(outcomes(lambda o, t: command(dz=0.5, grip=-1.0), start="align"), "dropped")


def test_the_scripted_expert_aligns_and_successes_need_both_arms():
    expert = ScriptedExpert(TASK)
    report = outcomes(lambda o, t: expert(o), episodes=8)
    aligned = report.counts[:, OUTCOMES.index("aligned")]
    assert aligned.min() >= 6, report.table()
    assert report.success.sum() <= aligned.min()
    assert report.success_rate >= 0.75


def test_the_table_names_only_the_outcomes_that_occurred():
    report = outcomes(lambda o, t: command(grip=-1.0), start="grasp")
    table = report.table()
    assert "reached, not closed" in table and "still" not in table and "left" in table


def test_copies_of_another_task_are_refused():
    class NoSubtasks:
        has_subtasks = False

    with pytest.raises(ValueError, match="Baxter"):
        link_outcomes(lambda o: o, NoSubtasks(), TASK)
