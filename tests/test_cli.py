"""The `dualarm` command as a user types it: outputs, headers, and one-line errors."""

import subprocess
import sys

import numpy as np
import pytest
import scipy.io

from dualarm.cli.main import main
from dualarm.cli.quickstart import EXAMPLE_RECORDING
from dualarm.kinematics import BAXTER_JOINT_LIMITS
from dualarm.mocap.io import read_recording, write_csv, write_sto
from dualarm.mocap.joint_angles import JOINT_COLUMNS
from dualarm.mocap.recording import SENSORS
from dualarm.mocap.synthetic import example_motion, example_recording, random_mountings, synthetic_recording

HEADER = "time," + ",".join(f"{arm}_q{k}" for arm in ("left", "right") for k in range(1, 8))


@pytest.fixture
def motion():
    t, q = example_motion(duration_s=8.0, rate_hz=50.0, calib_s=1.5)
    return t, q, synthetic_recording(t, q, mountings=random_mountings(np.random.default_rng(3)))


@pytest.fixture
def recording_csv(tmp_path, motion):
    path = tmp_path / "rec.csv"
    write_csv(motion[2], path)
    return path


def _table(path):
    lines = path.read_text().splitlines()
    return lines[0], np.loadtxt(path, delimiter=",", skiprows=1)


def test_help_on_every_command(capsys):
    for argv in (["--help"], ["mocap", "--help"], ["mocap", "joints", "--help"], ["mocap", "plot", "--help"],
                 ["mocap", "example", "--help"], ["quickstart", "--help"]):
        with pytest.raises(SystemExit) as exit_info:
            main(argv)
        assert exit_info.value.code == 0
        assert "usage: dualarm" in capsys.readouterr().out


def test_joints_writes_human_angles(tmp_path, motion, recording_csv):
    t, q, _ = motion
    out = tmp_path / "joints.csv"
    assert main(["mocap", "joints", str(recording_csv), "-o", str(out)]) == 0
    header, data = _table(out)
    assert header == HEADER and header.split(",")[1:] == list(JOINT_COLUMNS)
    assert data.shape == (len(t), 15)
    np.testing.assert_array_equal(data[:, 0], t)
    np.testing.assert_allclose(data[:, 1:], q, atol=1e-6)
    assert np.max(np.abs(data[t <= 1.0, 1:])) < 1e-6  # still in the calibration window


def test_joints_robot_is_clipped_baxter_vector(tmp_path, motion, recording_csv):
    out = tmp_path / "robot.csv"
    assert main(["mocap", "joints", str(recording_csv), "-o", str(out), "--robot", "-q"]) == 0
    header, data = _table(out)
    assert header == HEADER
    limits = np.tile(BAXTER_JOINT_LIMITS, (2, 1))
    assert np.all(data[:, 1:] >= limits[:, 0]) and np.all(data[:, 1:] <= limits[:, 1])
    np.testing.assert_allclose(data[:, 1:], np.clip(motion[1], limits[:, 0], limits[:, 1]), atol=1e-6)


def test_calib_seconds_option(tmp_path, recording_csv):
    out = tmp_path / "joints.csv"
    assert main(["mocap", "joints", str(recording_csv), "-o", str(out), "--calib-seconds", "0.5", "-q"]) == 0
    assert _table(out)[1].shape[1] == 15


def test_sto_and_mat_inputs(tmp_path, motion):
    t, q, rec = motion
    sto = tmp_path / "rec.sto"
    write_sto(rec, sto)
    mat = tmp_path / "rec.mat"
    scipy.io.savemat(mat, {"t": t, **{s: {"quat": rec.quat[s], "acc": np.zeros((len(t), 3)),
                                          "gyr": np.zeros((len(t), 3))} for s in SENSORS}})
    for path in (sto, mat):
        out = tmp_path / f"{path.suffix[1:]}.csv"
        assert main(["mocap", "joints", str(path), "-o", str(out), "-q"]) == 0
        np.testing.assert_allclose(_table(out)[1][:, 1:], q, atol=1e-6)


def _corrupt(path, transform):
    lines = path.read_text().splitlines()
    path.write_text("\n".join(transform(lines)) + "\n")
    return path


def _drop_column(name):
    def transform(lines):
        cells = [line.split(",") for line in lines]
        k = cells[0].index(name)
        return [",".join(c[:k] + c[k + 1:]) for c in cells]
    return transform


def _set_cell(row, name, value):
    def transform(lines):
        k = lines[0].split(",").index(name)
        cells = lines[row].split(",")
        cells[k] = value
        lines[row] = ",".join(cells)
        return lines
    return transform


def _zero_quaternion(row, sensor):
    def transform(lines):
        for part in "wxyz":
            lines = _set_cell(row, f"{sensor}_q{part}", "0")(lines)
        return lines
    return transform


BAD_INPUTS = {
    "missing column": (_drop_column("right_hand_qy"), ["right_hand_qy"]),
    "NaN quaternion": (_set_cell(5, "left_forearm_qx", "nan"), ["row 5", "left_forearm_qx"]),
    "zero quaternion": (_zero_quaternion(7, "right_upper_arm"), ["row 7", "right_upper_arm", "zero"]),
    "time not increasing": (_set_cell(10, "time", "0.05"), ["row 10", "time", "increasing"]),
    "empty file": (lambda lines: [], ["empty"]),
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_input_one_line_no_output(tmp_path, recording_csv, capfd, case):
    transform, words = BAD_INPUTS[case]
    _corrupt(recording_csv, transform)
    out = tmp_path / "joints.csv"
    code = main(["mocap", "joints", str(recording_csv), "-o", str(out)])
    err = capfd.readouterr().err.strip().splitlines()
    assert code != 0 and not out.exists()
    assert len(err) == 1 and str(recording_csv) in err[0], err
    for word in words:
        assert word.lower() in err[0].lower(), (word, err[0])
    assert "Traceback" not in err[0]


def test_calibration_longer_than_recording(tmp_path, recording_csv, capfd):
    out = tmp_path / "joints.csv"
    assert main(["mocap", "joints", str(recording_csv), "-o", str(out), "--calib-seconds", "60"]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "longer than the recording" in err[0] and str(recording_csv) in err[0]
    assert not out.exists()


def test_unknown_extension_and_missing_file(tmp_path, capfd):
    weird = tmp_path / "rec.xlsx"
    weird.write_text("time\n0\n")
    for path in (weird, tmp_path / "nope.csv"):
        out = tmp_path / "joints.csv"
        assert main(["mocap", "joints", str(path), "-o", str(out)]) == 2
        err = capfd.readouterr().err.strip().splitlines()
        assert len(err) == 1 and str(path) in err[0] and not out.exists()


def test_installed_entry_point_reports_errors_without_traceback(tmp_path):
    """The real `dualarm` process: exit status 2 and a single stderr line."""
    bad = tmp_path / "bad.csv"
    bad.write_text("time,foo\n0,1\n")
    proc = subprocess.run([sys.executable, "-m", "dualarm.cli.main", "mocap", "joints", str(bad), "-o",
                           str(tmp_path / "o.csv")], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr and "left_upper_arm" in proc.stderr


def test_shipped_example_is_the_generator_output():
    shipped, regenerated = read_recording(EXAMPLE_RECORDING), example_recording()
    np.testing.assert_array_equal(shipped.time, regenerated.time)
    for s in SENSORS:   # NumPy 1.26 and 2.x round a few quaternions 1 ulp apart
        np.testing.assert_allclose(shipped.quat[s], regenerated.quat[s], rtol=0, atol=1e-12)


def test_quickstart_writes_tables_and_figures(tmp_path, capsys):
    assert main(["quickstart", "-o", str(tmp_path)]) == 0
    names = {p.name for p in tmp_path.iterdir()}
    assert {"human_joint_angles.csv", "baxter_joint_angles.csv", "stick_figures.png",
            "human_joint_angles.png", "baxter_joint_angles.png", "residuals.png"} <= names
    text = capsys.readouterr().out
    assert "right_forearm: heading offset +25.0 deg" in text or "right_forearm: heading offset +25.1 deg" in text
    # The example's motion comes back through noise and heading offsets to within a degree.
    _, q = example_motion()
    got = np.loadtxt(tmp_path / "human_joint_angles.csv", delimiter=",", skiprows=1)[:, 1:]
    assert np.degrees(np.max(np.abs(got - q))) < 1.5


def test_sensor_map_option(tmp_path, motion):
    t, q, rec = motion
    renamed = {s: "IMU" + str(i) for i, s in enumerate(SENSORS)}
    path = tmp_path / "renamed.csv"
    write_csv(rec, path)
    lines = path.read_text().splitlines()
    header = lines[0]
    for s, new in renamed.items():
        header = header.replace(s + "_", new + "_")
    path.write_text("\n".join([header] + lines[1:]) + "\n")
    out = tmp_path / "joints.csv"
    assert main(["mocap", "joints", str(path), "-o", str(out), "-q"]) == 2  # names unknown
    mapping = ",".join(f"{new}={s}" for s, new in renamed.items())
    assert main(["mocap", "joints", str(path), "-o", str(out), "-q", "--sensor-map", mapping]) == 0
    np.testing.assert_allclose(_table(out)[1][:, 1:], q, atol=1e-6)


def _walk(parser, path=()):
    import argparse

    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _walk(sub, path + (name,))
        else:
            yield path, action


def test_every_option_of_every_command_says_what_it_does():
    """Walk the whole argparse tree: any option (or positional) without help text fails."""
    import argparse

    from dualarm.cli.main import build_parser

    missing = [" ".join(path) + " " + "/".join(a.option_strings or [a.dest])
               for path, a in _walk(build_parser())
               if a.help is None and not isinstance(a, argparse._HelpAction)]
    assert not missing, missing


def test_each_concept_has_one_spelling_across_commands():
    """Walk the whole argparse tree: an option's destination has one spelling (its first long
    option) in every command, and no two spellings differ only by a plural or a "-dir" (as
    --actor/--actors and --demos/--demo-dir once did). Older spellings stay as aliases after
    the one spelling."""
    import argparse
    import re

    from dualarm.cli.main import build_parser

    spellings, stems = {}, {}
    for path, a in _walk(build_parser()):
        long = [f for f in a.option_strings if f.startswith("--")]
        if not long or isinstance(a, argparse._HelpAction):
            continue
        spellings.setdefault(a.dest, set()).add(long[0])
        stems.setdefault(re.sub(r"(-dir|s)$", "", long[0][2:]), set()).add(long[0])
    assert not {d: s for d, s in spellings.items() if len(s) > 1}
    lists = {"condition", "seed"}     # one in train, a list of them in compare and pipeline
    assert not {stem: s for stem, s in stems.items() if len(s) > 1 and stem not in lists}


def test_a_missing_optional_package_is_one_line_naming_the_extra(tmp_path, monkeypatch, capsys):
    import sys

    from dualarm.cli.main import main

    monkeypatch.setitem(sys.modules, "toppra", None)        # as if the extra were not installed
    monkeypatch.setitem(sys.modules, "toppra.algorithm", None)
    src = tmp_path / "t.csv"
    src.write_text("time," + ",".join(f"{a}_{j}" for a in ("left", "right")
                                      for j in ("s0", "s1", "e0", "e1", "w0", "w1", "w2"))
                   + ",grip_left,grip_right\n"
                   + "\n".join(f"{t}," + ",".join(["0"] * 16) for t in (0.0, 0.5, 1.0)) + "\n")
    assert main(["export", str(src), "--format", "baxter", "-o", str(tmp_path / "b.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install 'dualarm[export]'" in err and "toppra" in err


def test_env_commands_default_to_trains_condition_with_the_shipped_constraints(capsys):
    """`env` takes train's default condition (multi, the shipped constraints): one default
    across commands (it was none for env, multi for train)."""
    from dualarm.cli.main import build_parser, main
    from dualarm.training import TrainConfig

    for argv in (["video", "-o", "x.mp4"], ["expert"], ["strip", "-o", "x.png"]):
        args = build_parser().parse_args(["env", *argv])
        assert args.condition == TrainConfig().condition == "multi"
    assert main(["env", "expert", "--episodes", "1"]) == 0
    assert "condition multi" in capsys.readouterr().out


def test_ctrl_c_outside_a_commands_own_handler_is_one_line(monkeypatch, capsys, tmp_path):
    """Ctrl-C while a command sets up (a run loading, a recording mapping) ends with one line
    and the shell's code for it, not a traceback; nothing is written."""
    import dualarm.cli.mocap as mocap

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(mocap, "map_file", interrupted)
    out = tmp_path / "out.csv"
    assert main(["mocap", "joints", str(EXAMPLE_RECORDING), "-o", str(out)]) == 130
    assert capsys.readouterr().err.strip() == "dualarm: interrupted" and not out.exists()
