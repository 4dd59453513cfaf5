"""Tests of dualarm.demos: the demonstration generator, the shipped set, and the whole path to constraints."""

from __future__ import annotations

import gzip

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dualarm.cli.main import main
from dualarm.constraints.extraction import extract_constraints
from dualarm.demos.formats import read_grip_events
from dualarm.demos.labels import read_labels
from dualarm.demos.loading import baxter_joints, DemoJoints, load_demo_dir
from dualarm.demos.segmentation import hand_points
from dualarm.demos.formats import DEFAULT_DEMO_DIR, GRIP_COLUMNS
from dualarm.sim_demos.generate import generate_demos, HumanModel, swivel, time_warp, tremor, write_demo_set
from dualarm.errors import InputError
from dualarm.kinematics import baxter_arm
from dualarm.mocap.io import read_recording
from dualarm.mocap.recording import SENSORS

SHIPPED = sorted(p.name for p in DEFAULT_DEMO_DIR.iterdir())
HUMAN = HumanModel()


@pytest.fixture(scope="module")
def generated():
    """The default set, generated afresh (``generate_demos(10, seed=0)``)."""
    return generate_demos(10, 0)


# --------------------------------------------------------------------------- the shipped set

def test_shipped_set_layout():
    assert SHIPPED == [f"demo_{k:02d}.csv.gz" for k in range(10)] + ["labels.csv", "scene.csv"]
    total = sum((DEFAULT_DEMO_DIR / name).stat().st_size for name in SHIPPED)
    assert total < 1_000_000                                      # small: compressed, six decimals
    header = gzip.open(DEFAULT_DEMO_DIR / "demo_00.csv.gz", "rt").readline().strip().split(",")
    assert header[0] == "time" and header[-2:] == list(GRIP_COLUMNS)
    rec = read_recording(DEFAULT_DEMO_DIR / "demo_00.csv.gz")     # the reader of `dualarm mocap joints`
    assert set(rec.quat) == set(SENSORS) and rec.rate_hz == pytest.approx(100.0)


def test_regenerates_the_shipped_set_bit_for_bit(generated, tmp_path):
    paths = write_demo_set(generated, tmp_path)
    assert sorted(p.name for p in paths) == SHIPPED
    for name in SHIPPED:
        assert (tmp_path / name).read_bytes() == (DEFAULT_DEMO_DIR / name).read_bytes(), name


def test_cli_generate_matches_the_api(tmp_path, capsys):
    # Demonstrations are drawn one after another: the first two of --count 2 are the shipped first two.
    assert main(["demos", "generate", "-o", str(tmp_path), "--count", "2", "--seed", "0", "-q"]) == 0
    for name in ("demo_00.csv.gz", "demo_01.csv.gz"):
        assert (tmp_path / name).read_bytes() == (DEFAULT_DEMO_DIR / name).read_bytes()
    shipped_rows = (DEFAULT_DEMO_DIR / "labels.csv").read_text().splitlines()
    assert (tmp_path / "labels.csv").read_text().splitlines() == shipped_rows[:13]
    with pytest.raises(SystemExit) as info:
        main(["demos", "generate", "-o", str(tmp_path / "x"), "--count", "0"])
    assert info.value.code == 2 and not (tmp_path / "x").exists()
    with pytest.raises(InputError, match="count"):
        generate_demos(0)


# --------------------------------------------------------------------------- what a demonstration holds

def test_labels_file_holds_the_generating_windows(generated):
    labels = read_labels(DEFAULT_DEMO_DIR / "labels.csv")
    for d in generated:
        np.testing.assert_allclose(labels[d.name].windows, d.windows, atol=5.1e-5)


def test_timeline_calibration_pose_and_sub_tasks(generated):
    h = HUMAN
    for d in generated:
        assert d.time[0] == 0 and np.allclose(np.diff(d.time), 1 / h.rate_hz)
        calib = d.time < h.calib_s
        assert np.abs(d.q[calib]).max() < 0.005                  # the zero pose, tremor only
        w = d.windows
        np.testing.assert_array_equal(w[:, :2, 1], w[:, 1:, 0])  # reach -> grasp -> align, no gaps
        assert np.all(w[:, 0, 0] > h.calib_s + h.raise_delay_s[0] + h.raise_s[0])
        assert w[:, 2, 1].max() == pytest.approx(d.time[-1] - h.end_hold_s, abs=1.5 / h.rate_hz)
        for a in range(2):                                        # the hand closes during reach's end or grasp
            closing = d.time[np.argmax(d.grip[:, a])]
            assert w[a, 0, 0] < closing <= w[a, 1, 1]
            assert np.all(d.grip[d.time < w[a, 0, 0], a] == 0)
    # Human variability: each demo has its own pace, and the two arms their own timing.
    durations = np.array([d.windows[:, 2, 1] - d.windows[:, 0, 0] for d in generated])
    assert durations.std() > 0.1
    assert sum(not np.allclose(d.windows[0], d.windows[1]) for d in generated) == len(generated)
    assert len({d.env_seed for d in generated}) == len(generated)


def test_swivel_changes_the_arm_but_not_the_hand(generated):
    # Every expert episode starts in the same home posture; the demos start from it turned
    # about the shoulder-wrist axis by their own swivel, with the hand where the robot's is.
    starts = np.array([d.q[np.searchsorted(d.time, d.windows[0, 0, 0]), :7] for d in generated])
    homes = np.array([d.expert_q[0, :7] for d in generated])
    assert np.ptp(homes, axis=0).max() < 1e-6
    assert np.ptp(starts, axis=0).max() > 0.1
    left = baxter_arm("left")
    hand = left.forward(starts)[:, -1, :3, 3]
    assert np.abs(hand - left.forward(homes)[:, -1, :3, 3]).max() < 0.004      # tremor: a few mm at most
    # ... and the task ends where the expert's does.
    end = np.array([d.q[-1] for d in generated])
    np.testing.assert_allclose(hand_points(end), hand_points(np.array([d.expert_q[-1] for d in generated])),
                               atol=0.004)


def _elbow_turn(model, q):
    """Angle (rad) of the elbow about the shoulder->wrist axis, from an arbitrary fixed reference."""
    p = model.joint_positions(q)
    axis = p[:, 5] - p[:, 1]
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    off = p[:, 3] - p[:, 1]
    off -= (off * axis).sum(axis=1, keepdims=True) * axis
    ref = np.cross(axis, [0.0, 0.0, 1.0])
    return np.arctan2((np.cross(ref, off) * axis).sum(axis=1), (ref * off).sum(axis=1))


def test_swivel_unit(generated):
    model = baxter_arm("right")
    q = generated[3].expert_q[::4, 7:]
    before = model.forward(q)[:, -1]
    for amount in (0.2, -0.2):
        moved = swivel(model, q, amount)
        np.testing.assert_allclose(model.forward(moved)[:, -1], before, atol=1e-9)
        step = np.linalg.norm(moved - q, axis=1)
        assert np.all((step > 0.95 * abs(amount)) & (step <= abs(amount) + 1e-6))
        turn = np.angle(np.exp(1j * (_elbow_turn(model, moved) - _elbow_turn(model, q))))
        assert np.all(np.sign(turn) == np.sign(amount)) and np.all(np.abs(turn) > 0.02)
    np.testing.assert_allclose(swivel(model, q, 0.0), q, atol=1e-12)


def test_time_warp_hits_the_knots_and_rests_at_the_ends():
    human = np.array([2.0, 3.5, 4.2, 5.6])
    expert = np.array([0.0, 0.2, 0.3, 0.52])
    t = np.linspace(0, 8, 8001)
    tau = time_warp(t, human, expert)
    np.testing.assert_allclose(time_warp(human, human, expert), expert, atol=1e-12)
    assert np.all(np.diff(tau) >= -1e-12)
    assert np.all(tau[t <= 2.0] == 0.0) and np.all(tau[t >= 5.6] == 0.52)
    slope = np.gradient(tau, t)
    assert abs(slope[np.searchsorted(t, 2.0) + 1]) < 1e-2 and abs(slope[np.searchsorted(t, 5.6) - 1]) < 1e-2
    assert slope.max() > 0.1


def test_tremor_rms_and_band():
    rng = np.random.default_rng(1)
    x = tremor(rng, 5000, 100.0, np.array([0.001, 0.003]), (8.0, 12.0))
    np.testing.assert_allclose(np.sqrt((x ** 2).mean(axis=0)), [0.001, 0.003], rtol=1e-9)
    power = np.abs(np.fft.rfft(x[:, 1])) ** 2
    f = np.fft.rfftfreq(5000, 0.01)
    assert power[(f > 6.5) & (f < 13.5)].sum() / power.sum() > 0.9


def test_sensor_mountings_are_random(generated):
    rec = generated[0].recording
    q0 = {s: Rotation.from_quat(rec.quat[s][0], scalar_first=True) for s in SENSORS}
    # In the zero pose the three segments of an arm are aligned; their sensors are not.
    for arm in ("left", "right"):
        a, b, c = (q0[f"{arm}_{seg}"] for seg in ("upper_arm", "forearm", "hand"))
        assert min((a.inv() * b).magnitude(), (b.inv() * c).magnitude()) > np.deg2rad(5)


def test_gripper_events_round_trip(generated, tmp_path):
    np.testing.assert_array_equal(read_grip_events(DEFAULT_DEMO_DIR / "demo_04.csv.gz"), generated[4].grip)
    text = gzip.open(DEFAULT_DEMO_DIR / "demo_04.csv.gz", "rt").read().splitlines()
    text[5] = text[5][:-3] + "0,7"
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(text) + "\n")
    with pytest.raises(InputError, match=r"bad.csv, row 5, column 'right_grip': gripper event must be 0 or 1"):
        read_grip_events(bad)


# --------------------------------------------------------------------------- end to end

def test_imu_recordings_give_the_constraints_of_the_generating_trajectories(generated):
    """IMU CSVs -> calibration -> joint angles -> Baxter -> Eq. 12, against Eq. 12 on the truth."""
    from_imu, labels = load_demo_dir(DEFAULT_DEMO_DIR)
    truth = [DemoJoints(d.name, d.time, baxter_joints(d.time, d.q)) for d in generated]
    worst = 0.0
    for spec in ("reach+grasp+align", "reach+grasp,align", "reach,grasp,align"):
        a = extract_constraints(from_imu, labels, spec)
        b = extract_constraints(truth, labels, spec)
        for sa, sb in zip(a.segments, b.segments):
            worst = max(worst, np.abs(sa.lower - sb.lower).max(), np.abs(sa.upper - sb.upper).max())
    assert worst < 0.01
    # The bounds are not trivially equal: the recordings carry noise and unknown mountings.
    assert worst > 1e-4


# --------------------------------------------------------------------------- the scene file

def test_the_shipped_scene_is_where_the_generator_placed_the_boxes_and_targets(generated):
    """scene.csv holds each demonstration's resting box centres and targets (0.1 mm), as the
    environment placed them at the demonstration's reset seed; a folder's scene file is not
    taken for a recording."""
    from dualarm.demos.formats import demo_files
    from dualarm.demos.scene import demo_scenes
    from dualarm.envs.config import TaskConfig

    task = TaskConfig()
    scenes = demo_scenes(DEFAULT_DEMO_DIR, [d.name for d in generated], task.workspace())
    for d in generated:
        np.testing.assert_allclose(scenes[d.name].boxes, d.scene.boxes, atol=5e-5)
        np.testing.assert_allclose(scenes[d.name].targets, d.scene.targets, atol=5e-5)
        rest = task.scene.table_height + task.scene.box_half_size
        np.testing.assert_allclose(d.scene.boxes[:, 2], rest, atol=2e-3)   # resting on the table
        assert d.scene.boxes[0, 1] > 0 > d.scene.boxes[1, 1]              # left box on the left
    assert "scene" not in demo_files(DEFAULT_DEMO_DIR)


@pytest.mark.parametrize("edit,column,phrase", [
    (lambda rows: rows[1].__setitem__(2, "1.5"), "left_box_y", "outside the workspace"),
    (lambda rows: rows[1].__setitem__(3, "0.95"), "left_box_z", "rests on the table"),
    (lambda rows: rows[1].__setitem__(9, "0.5"), "left_target_z", "between the table top"),
    (lambda rows: rows[1].__setitem__(4, "nan"), "right_box_x", "finite number"),
    (lambda rows: rows[1].__setitem__(4, "abc"), "right_box_x", "finite number"),
    (lambda rows: [r.pop(5) for r in rows], "right_box_y", "missing column"),
    (lambda rows: rows[2].__setitem__(0, "demo_00"), "demo", "given twice"),
])
def test_a_bad_scene_gets_one_error_naming_the_file_row_and_column(tmp_path, edit, column, phrase):
    from dualarm.demos.scene import read_scenes
    from dualarm.envs.config import TaskConfig

    rows = [line.split(",") for line in (DEFAULT_DEMO_DIR / "scene.csv").read_text().splitlines()]
    edit(rows)
    path = tmp_path / "scene.csv"
    path.write_text("\n".join(",".join(r) for r in rows) + "\n")
    with pytest.raises(InputError, match=phrase) as err:
        read_scenes(path, TaskConfig().workspace())
    assert err.value.column == column and str(path) in str(err.value)


def test_a_folder_without_its_scene_or_a_row_for_a_demonstration_is_named(tmp_path):
    from dualarm.demos.scene import demo_scenes
    from dualarm.envs.config import TaskConfig

    workspace = TaskConfig().workspace()
    with pytest.raises(InputError, match="scene file not found"):
        demo_scenes(tmp_path, ["demo_00"], workspace)
    lines = (DEFAULT_DEMO_DIR / "scene.csv").read_text().splitlines()
    (tmp_path / "scene.csv").write_text("\n".join(lines[:3]) + "\n")      # demo_00 and demo_01
    with pytest.raises(InputError, match="no scene row for demonstration.s. demo_02"):
        demo_scenes(tmp_path, ["demo_00", "demo_02"], workspace)
    assert set(demo_scenes(tmp_path, ["demo_01"], workspace)) == {"demo_01"}
