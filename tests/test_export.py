"""From a trajectory to a robot: time parameterisation within Baxter's limits, the Baxter SDK
and ROS 2 formats read back, the ONNX policy against PyTorch, replay in the simulator, and
bad input refused with one line and no file."""

import csv

import numpy as np
import pytest

from dualarm.cli.main import main
from dualarm.envs.baxter import BaxterReachGraspAlign, home_posture
from dualarm.envs.config import TaskConfig
from dualarm.envs.rollout import make_policy, run_episode
from dualarm.errors import InputError
from dualarm.export.formats import (BAXTER_COLUMNS, TOPICS, read_ros2_trajectories,
                                    write_baxter_csv, write_ros2_bag)
from dualarm.export.retime import Limits, retime
from dualarm.export.trajectory import (CSV_COLUMNS, JointTrajectory, from_episode,
                                       read_trajectory_csv, write_trajectory_csv)

HOME = home_posture(TaskConfig()).reshape(14)
#: Per joint amplitude (rad) of the test motion: every joint moves, shoulders the most.
AMPLITUDE = np.tile([0.3, 0.25, 0.2, 0.3, 0.4, 0.3, 0.5], 2)


def smooth_motion(duration: float, points: int = 21) -> JointTrajectory:
    """Rest to rest: q(t) = home + A (1 - cos(pi t / T)) / 2, the grips closing on the way.
    Peak velocity pi A / (2T), peak acceleration pi^2 A / (2 T^2)."""
    t = np.linspace(0.0, duration, points)
    phase = 0.5 * (1 - np.cos(np.pi * t / duration))
    joints = HOME + phase[:, None] * AMPLITUDE
    return JointTrajectory(t, joints, np.repeat(phase[:, None], 2, axis=1))


def test_a_trajectory_within_the_limits_keeps_its_shape_and_timing():
    slow = smooth_motion(6.0)               # peak 0.13 rad/s and 0.07 rad/s^2: far inside
    r = retime(slow)
    # at rest at both ends: the first and last grid steps (1/8 of a segment) take twice as long
    np.testing.assert_allclose(r.waypoint_time, slow.time, atol=0.08)
    assert r.duration == pytest.approx(6.0, abs=0.08)
    rep = r.report()
    assert rep["waypoint_deviation_rad"] < 1e-9
    samples = r.sample(100)
    exact = HOME + 0.5 * (1 - np.cos(np.pi * samples.time / 6.0))[:, None] * AMPLITUDE
    assert np.abs(samples.joints - exact).max() < 0.01          # the same curve in time


def test_a_trajectory_beyond_the_limits_comes_out_slower_and_within_them():
    fast = smooth_motion(0.2)               # 40x Baxter's velocity limits on the wrists
    limits = Limits.baxter()
    r = retime(fast, limits)
    rep = r.report()
    assert r.duration > 1.0
    assert rep["velocity_ratio"].max() <= 1.001 and rep["acceleration_ratio"].max() <= 1.001
    assert rep["acceleration_ratio"].max() > 0.9       # time-optimal: some limit is reached
    assert rep["waypoint_deviation_rad"] < 1e-9        # through every waypoint
    samples = r.sample(100)
    assert (np.diff(samples.time) > 0).all() and samples.time[0] == 0.0
    assert samples.time[-1] == pytest.approx(r.duration)
    assert np.abs(samples.velocity[[0, -1]]).max() < 1e-6          # starts and ends at rest
    # continuous velocity: no jump larger than the acceleration limit allows in one sample
    jump = np.abs(np.diff(samples.velocity, axis=0)).max(axis=0)
    assert (jump <= limits.acceleration * 0.01 * 1.01 + 1e-9).all()


def test_scaling_the_limits_scales_the_motion_down():
    fast = smooth_motion(0.2)
    full, half = retime(fast), retime(fast, Limits.baxter(0.5, 0.5))
    assert half.duration > 1.3 * full.duration
    assert half.report()["velocity_ratio"].max() <= 1.001


def test_a_joint_at_rest_between_waypoints_stays_still_and_both_arms_share_the_clock():
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    joints = np.repeat(HOME[None], 5, axis=0)
    joints[:, 0] += [0.0, 0.2, 0.2, 0.2, 0.5]          # left s0 moves, rests, moves
    joints[:, 7] -= [0.0, 0.0, 0.1, 0.3, 0.3]          # right s0 starts later
    r = retime(JointTrajectory(t, joints, np.zeros((5, 2))))
    s = r.sample(500)
    between = (s.time > r.waypoint_time[1] + 1e-6) & (s.time < r.waypoint_time[3] - 1e-6)
    assert np.abs(s.joints[between, 0] - HOME[0] - 0.2).max() < 1e-9       # no overshoot
    assert np.abs(s.joints[:, [1, 2, 3, 4, 5, 6, 8]] - HOME[[1, 2, 3, 4, 5, 6, 8]]).max() < 1e-9
    assert (np.diff(r.waypoint_time) > 0).all()


def test_our_csv_round_trips(tmp_path):
    original = smooth_motion(1.0)
    write_trajectory_csv(tmp_path / "t.csv", original)
    back = read_trajectory_csv(tmp_path / "t.csv")
    assert np.abs(back.joints - original.joints).max() < 1e-6
    np.testing.assert_allclose(back.time, original.time, atol=1e-6)


def test_baxter_sdk_file_has_the_playback_columns_and_gripper_percent(tmp_path):
    samples = retime(smooth_motion(2.0)).sample(100)
    write_baxter_csv(tmp_path / "b.csv", samples)
    with open(tmp_path / "b.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert tuple(rows[0]) == BAXTER_COLUMNS == (
        "time", "left_s0", "left_s1", "left_e0", "left_e1", "left_w0", "left_w1", "left_w2",
        "left_gripper", "right_s0", "right_s1", "right_e0", "right_e1", "right_w0", "right_w1",
        "right_w2", "right_gripper")
    data = np.array(rows[1:], dtype=float)
    assert len(data) == len(samples.time) and (np.diff(data[:, 0]) > 0).all()
    np.testing.assert_allclose(data[:, 1:8], samples.joints[:, :7], atol=1e-6)
    np.testing.assert_allclose(data[:, 9:16], samples.joints[:, 7:], atol=1e-6)
    assert data[0, 8] == 100.0 and data[-1, 16] == 0.0      # open at the start, closed at the end


def test_ros2_bag_reads_back_point_for_point(tmp_path):
    samples = retime(smooth_motion(1.0)).sample(50)
    write_ros2_bag(tmp_path / "bag", samples, start_ns=1_700_000_000_000_000_000)
    assert sorted(p.name for p in (tmp_path / "bag").iterdir()) == ["bag.mcap", "metadata.yaml"]
    assert [p.name for p in tmp_path.iterdir()] == ["bag"]          # no temporary left over
    write_ros2_bag(tmp_path / "new" / "folder" / "bag", samples)    # made, as other formats do
    assert (tmp_path / "new" / "folder" / "bag" / "metadata.yaml").is_file()
    msgs = read_ros2_trajectories(tmp_path / "bag")
    arm = msgs[TOPICS["trajectory"]]
    assert list(arm.joint_names) == [c for c in CSV_COLUMNS[1:15]]
    assert len(arm.points) == len(samples.time)
    for k, p in enumerate(arm.points):
        np.testing.assert_array_equal(p.positions, samples.joints[k])
        np.testing.assert_array_equal(p.velocities, samples.velocity[k])
        np.testing.assert_array_equal(p.accelerations, samples.acceleration[k])
        t = p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec
        assert t == pytest.approx(samples.time[k], abs=1e-9)
    grip = msgs[TOPICS["gripper"]]
    assert list(grip.joint_names) == ["left_gripper", "right_gripper"]
    np.testing.assert_allclose([p.positions for p in grip.points], 100 * (1 - samples.grip))
    states = msgs[TOPICS["states"]]
    assert len(states) == len(samples.time)
    assert states[-1].header.stamp.sec == 1_700_000_000 + int(samples.time[-1])


def test_onnx_policy_matches_pytorch_on_1000_observations(tmp_path):
    import torch

    from dualarm.export.onnx_policy import export_onnx, onnx_actions
    from dualarm.rl.config import DADDPGConfig
    from dualarm.rl.daddpg import DADDPG

    agent = DADDPG(DADDPGConfig(hidden=(64, 64)), (30, 30), (4, 4), seed=0)
    rng = np.random.default_rng(0)
    agent.normalizer.update(rng.normal(2.0, 3.0, (500, 2, 30)))
    with torch.no_grad():
        for p in agent.actor.parameters():          # weights a trained actor might have
            p += 0.3 * torch.randn(p.shape, generator=torch.Generator().manual_seed(1))
    export_onnx(agent, tmp_path / "policy.onnx")
    obs = rng.normal(2.0, 3.0, (1000, 2, 30))
    ours, theirs = agent.act(obs), onnx_actions(tmp_path / "policy.onnx", obs)
    assert np.abs(ours).max() > 0.5                 # not a trivially zero policy
    assert np.abs(ours - theirs).max() < 1e-5


def expert_trajectory(seed: int) -> JointTrajectory:
    env = BaxterReachGraspAlign(TaskConfig(condition="none"))
    episode = run_episode(env, make_policy("expert", env), seed)
    assert episode.success
    return from_episode(episode, env.config.control_period)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_retimed_expert_still_puts_both_boxes_at_their_targets(seed):
    from dualarm.export.replay import replay

    r = retime(expert_trajectory(seed))
    assert r.duration > 5 * r.source.duration           # the simulator's 20 ms steps are fast
    success, frames = replay(r, TaskConfig(), seed, camera=None)
    assert success


# ------------------------------------------------------------------ the command, bad input
def good_csv(tmp_path):
    path = tmp_path / "in.csv"
    write_trajectory_csv(path, smooth_motion(1.0, points=6))
    return path


def spoil(path, row: int, column: str, value: str):
    lines = path.read_text().splitlines()
    k = CSV_COLUMNS.index(column)
    cells = lines[row].split(",")
    cells[k] = value
    lines[row] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("fmt", ["csv", "baxter", "ros2"])
def test_export_of_a_trajectory_file_writes_each_format(tmp_path, capsys, fmt):
    src = good_csv(tmp_path)
    out = tmp_path / f"out-{fmt}"
    extra = ["--retime"] if fmt == "csv" else []
    assert main(["export", str(src), "-o", str(out), "--format", fmt, "--plot",
                 str(tmp_path / "check.png"), *extra]) == 0
    printed = capsys.readouterr().out
    assert "time-parameterised" in printed and "right_w2" in printed
    assert out.exists() and (tmp_path / "check.png").stat().st_size > 10_000


@pytest.mark.parametrize("spoilt,phrase", [
    ((3, "time", "0.1"), "does not come after"),
    ((2, "left_e1", "nan"), "column left_e1: nan is not a finite number"),
    ((4, "right_s0", "2.5"), "column right_s0: 2.5000 rad is outside Baxter's limits"),
    ((2, "grip_left", "abc"), "column grip_left: 'abc' is not a number"),
])
def test_bad_trajectories_get_one_line_and_no_file(tmp_path, capsys, spoilt, phrase):
    src = good_csv(tmp_path)
    spoil(src, *spoilt)
    out = tmp_path / "out.csv"
    assert main(["export", str(src), "-o", str(out), "--format", "baxter"]) == 2
    err = capsys.readouterr().err.strip()
    assert phrase in err and str(src) in err and len(err.splitlines()) == 1
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["in.csv"]


def test_export_refuses_an_unknown_format_an_existing_output_and_its_input(tmp_path, capsys):
    src = good_csv(tmp_path)
    before = src.read_bytes()
    with pytest.raises(SystemExit) as exc:
        main(["export", str(src), "-o", str(tmp_path / "x"), "--format", "urdf"])
    assert exc.value.code == 2 and "invalid choice: 'urdf'" in capsys.readouterr().err
    (tmp_path / "there.csv").write_text("keep me\n")
    assert main(["export", str(src), "-o", str(tmp_path / "there.csv"), "--format", "baxter"]) == 2
    assert "exists already" in capsys.readouterr().err
    assert (tmp_path / "there.csv").read_text() == "keep me\n"
    assert main(["export", str(src), "-o", str(src), "--format", "baxter", "--retime"]) == 2
    assert "is also the input" in capsys.readouterr().err
    assert main(["export", str(src), "-o", str(tmp_path / "a.onnx"), "--format", "onnx"]) == 2
    assert "exports a run's policy" in capsys.readouterr().err
    assert src.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.csv", "there.csv"]


def test_a_trajectory_is_checked_where_it_is_made():
    with pytest.raises(InputError, match="at least 2 points"):
        JointTrajectory(np.zeros(1), HOME[None], np.zeros((1, 2))).check()
    with pytest.raises(InputError, match="velocity scale must be in"):
        Limits.baxter(velocity_scale=1.5)


def test_options_that_would_do_nothing_are_refused_before_anything_is_written(tmp_path, capsys):
    """--plot/--replay need a time-parameterised trajectory, --retime is csv's, and a plot must
    be a figure format: each is one line, and no output appears."""
    src = tmp_path / "t.csv"
    write_trajectory_csv(src, JointTrajectory(np.linspace(0, 1, 5), np.zeros((5, 14)), np.zeros((5, 2))))
    for argv, says in (
            (["--format", "csv", "--plot", str(tmp_path / "p.png")], "time-parameterised"),
            (["--format", "onnx", "--replay"], "time-parameterised"),
            (["--format", "baxter", "--retime"], "csv only")):
        out = tmp_path / "out.x"
        assert main(["export", str(src), "-o", str(out), *argv]) == 2, argv
        assert says in capsys.readouterr().err and not out.exists()
    with pytest.raises(SystemExit):
        main(["export", str(src), "-o", str(tmp_path / "o.csv"), "--retime", "--plot",
              str(tmp_path / "check.xyz")])
    assert "a figure must end in" in capsys.readouterr().err
    assert not (tmp_path / "o.csv").exists()
