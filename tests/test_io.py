"""Tests of dualarm.mocap.io: round trips, the real qmt .mat file, and every bad input."""

from __future__ import annotations

import gzip
import os
import sys
import types
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from scipy.spatial.transform import Rotation

from dualarm.errors import InputError
from dualarm.mocap import io
from dualarm.mocap.recording import SENSORS, Recording

REAL_MAT = Path(__file__).resolve().parents[2] / "shared" / "data" / "real-imu" / "qmt_full_body_example_data.mat"
QCOLS = [s + x for s in SENSORS for x in ("_qw", "_qx", "_qy", "_qz")]


def make_recording(T: int = 50, seed: int = 0, raw: bool = False) -> Recording:
    rng = np.random.default_rng(seed)
    time = 1.5 + np.cumsum(rng.uniform(0.005, 0.015, T))
    quat = {s: Rotation.random(T, rng=seed + k).as_quat(scalar_first=True) for k, s in enumerate(SENSORS)}
    acc = {s: rng.normal(0, 5, (T, 3)) for s in SENSORS[:2]} if raw else {}
    gyr = {s: rng.normal(0, 1, (T, 3)) for s in SENSORS[:2]} if raw else {}
    return Recording(time=time, quat=quat, acc=acc, gyr=gyr, source="made")


def assert_same(a: Recording, b: Recording, raw: bool = True) -> None:
    assert np.array_equal(a.time, b.time)
    for s in SENSORS:
        assert np.array_equal(a.quat[s], b.quat[s]), s
    if raw:
        for kind in ("acc", "gyr"):
            da, db = getattr(a, kind), getattr(b, kind)
            assert da.keys() == db.keys()
            for s in da:
                assert np.array_equal(da[s], db[s]), (kind, s)


def write_text(path: Path, header: list[str], rows: list[list]) -> Path:
    path.write_text("\n".join([",".join(header)] + [",".join(map(str, r)) for r in rows]) + "\n")
    return path


def table(rec: Recording) -> tuple[list[str], list[list]]:
    """The recording as CSV header + rows of Python values, for tests to spoil."""
    rows = [[float(rec.time[i])] + [float(v) for s in SENSORS for v in rec.quat[s][i]] for i in range(rec.n_samples)]
    return ["time"] + QCOLS, rows


# --------------------------------------------------------------------------- CSV


@pytest.mark.parametrize("name", ["rec.csv", "rec.csv.gz"])
@pytest.mark.parametrize("raw", [False, True])
def test_csv_round_trip_is_exact(tmp_path, name, raw):
    rec = make_recording(raw=raw)
    path = tmp_path / name
    io.write_csv(rec, path)
    back = io.read_recording(path)
    assert_same(rec, back)
    assert back.source == str(path)
    if name.endswith(".gz"):
        assert gzip.decompress(path.read_bytes()).startswith(b"time,left_upper_arm_qw,")


def test_write_csv_header_and_no_leftovers(tmp_path):
    rec = make_recording(T=3, raw=True)
    path = tmp_path / "rec.csv"
    io.write_csv(rec, path)
    header = path.read_text().splitlines()[0].split(",")
    assert header[:25] == ["time"] + QCOLS
    assert header[25:] == [s + x for s in SENSORS[:2] for x in ("_ax", "_ay", "_az", "_gx", "_gy", "_gz")]
    assert os.listdir(tmp_path) == ["rec.csv"]


def test_write_is_atomic(tmp_path, monkeypatch):
    path = tmp_path / "rec.csv"
    path.write_text("old")

    def crash(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(io.os, "replace", crash)
    with pytest.raises(InputError, match="No space left") as e:
        io.write_csv(make_recording(), path)
    assert str(path) in str(e.value)
    assert path.read_text() == "old"
    assert os.listdir(tmp_path) == ["rec.csv"]


def test_write_table_csv(tmp_path):
    data = np.random.default_rng(1).normal(size=(7, 3))
    path = tmp_path / "angles.csv"
    io.write_table_csv(path, ["time", "a", "b"], data)
    lines = path.read_text().splitlines()
    assert lines[0] == "time,a,b"
    assert np.array_equal(np.array([[float(v) for v in line.split(",")] for line in lines[1:]]), data)
    with pytest.raises(ValueError, match="shape"):
        io.write_table_csv(path, ["a"], data)


def test_csv_extra_columns_and_order_ignored(tmp_path):
    rec = make_recording(T=5)
    header, rows = table(rec)
    # Reverse the column order and add text and number columns the reader must ignore.
    header = ["label", "note_ax"] + header[::-1] + ["left_hand_ax"]
    rows = [["walk", 1.0] + r[::-1] + [3.0] for r in rows]
    back = io.read_csv(write_text(tmp_path / "x.csv", header, rows))
    assert_same(rec, back, raw=False)
    assert back.acc == {}  # left_hand_ax alone is not a raw accelerometer


def test_csv_quaternion_sign_either_way(tmp_path):
    rec = make_recording(T=6)
    flipped = {s: q * np.where(np.arange(6) % 2, -1.0, 1.0)[:, None] for s, q in rec.quat.items()}
    path = tmp_path / "x.csv"
    io.write_csv(Recording(time=rec.time, quat=flipped), path)
    back = io.read_csv(path)
    for s in SENSORS:
        assert np.array_equal(back.quat[s], flipped[s])


def test_csv_sensor_map_renames_prefixes(tmp_path):
    rec = make_recording(T=4)
    header, rows = table(rec)
    header = [h.replace("left_hand_", "LH_") for h in header]
    back = io.read_recording(write_text(tmp_path / "x.csv", header, rows), sensor_map={"LH": "left_hand"})
    assert_same(rec, back, raw=False)


# --------------------------------------------------------------------------- bad CSV input


def spoil(tmp_path: Path, how: str) -> tuple[Path, str | None, str | None]:
    """Write a bad CSV; returns its path, the row and the column the message must name."""
    header, rows = table(make_recording(T=5))
    path = tmp_path / f"{how}.csv"
    if how == "empty":
        path.write_text("")
        return path, None, None
    if how == "header_only":
        path.write_text(",".join(header) + "\n")
        return path, None, None
    col, row = "left_hand_qx", 3
    j = header.index(col)
    if how == "missing_column":
        del header[j]
        rows = [r[:j] + r[j + 1:] for r in rows]
        row = None
    elif how == "missing_time":
        col, row = "time", None
        rows = [r[1:] for r in rows]
        header = header[1:]
    elif how == "nan":
        rows[row - 1][j] = "nan"
    elif how in ("zero", "bad_norm"):
        col = "left_hand_qw..left_hand_qz"
        rows[row - 1][j - 1: j + 3] = [0.0] * 4 if how == "zero" else [1.0, 0.1, 0.0, 0.0]
    elif how == "time_equal":
        col = "time"
        rows[row - 1][0] = rows[row - 2][0]
    elif how == "time_decreasing":
        col = "time"
        rows[row - 1][0] = rows[row - 2][0] - 0.5
    elif how == "non_numeric":
        rows[row - 1][j] = "abc"
    elif how == "empty_cell":
        rows[row - 1][j] = ""
    elif how == "ragged":
        col = None
        rows[row - 1] = rows[row - 1][:-1]
    return write_text(path, header, rows), (None if row is None else f"row {row}"), col


@pytest.mark.parametrize("how, message", [
    ("empty", "empty file"),
    ("header_only", "no data rows"),
    ("missing_column", "missing column"),
    ("missing_time", "missing column"),
    ("nan", "NaN"),
    ("zero", "zero quaternion"),
    ("bad_norm", "norm"),
    ("time_equal", "not strictly increasing"),
    ("time_decreasing", "not strictly increasing"),
    ("non_numeric", "not a number: 'abc'"),
    ("empty_cell", "not a number: ''"),
    ("ragged", "row has 24 cells, the header 25"),
])
def test_csv_bad_input_names_file_row_and_column(tmp_path, how, message):
    path, row, col = spoil(tmp_path, how)
    with pytest.raises(InputError, match=message) as e:
        io.read_recording(path)
    text = str(e.value)
    assert text.startswith(str(path)), text
    assert e.value.source == str(path)
    if row:
        assert row in text, text
    else:
        assert "row " not in text, text
    if col:
        assert f"column '{col}" in text, text


def test_csv_missing_column_mentions_fusion_alternative(tmp_path):
    path, _, _ = spoil(tmp_path, "missing_column")
    with pytest.raises(InputError, match=r"column 'left_hand_qx'.*missing column$"):
        io.read_csv(path)
    header, rows = table(make_recording(T=3))
    keep = [j for j, h in enumerate(header) if not h.startswith("right_hand_q")]
    path = write_text(tmp_path / "gone.csv", [header[j] for j in keep], [[r[j] for j in keep] for r in rows])
    with pytest.raises(InputError, match=r"column 'right_hand_qw'.*sensor fusion"):
        io.read_csv(path)


def test_csv_duplicate_column(tmp_path):
    header, rows = table(make_recording(T=3))
    path = write_text(tmp_path / "dup.csv", header + ["time"], [r + [r[0]] for r in rows])
    with pytest.raises(InputError, match=r"column 'time'.*more than once"):
        io.read_csv(path)


# --------------------------------------------------------------------------- files and extensions


def test_unknown_extension(tmp_path):
    path = tmp_path / "rec.txt"
    path.write_text("time\n1\n")
    with pytest.raises(InputError, match=r"unknown file type.*\.csv, \.csv\.gz, \.sto, \.mat") as e:
        io.read_recording(path)
    assert str(path) in str(e.value)


@pytest.mark.parametrize("name", ["nope.csv", "nope.sto", "nope.mat", "nope.csv.gz"])
def test_missing_file(tmp_path, name):
    path = tmp_path / name
    with pytest.raises(InputError, match="file not found") as e:
        io.read_recording(path)
    assert str(path) in str(e.value)


def test_corrupt_gzip(tmp_path):
    path = tmp_path / "x.csv.gz"
    path.write_bytes(b"not gzip at all")
    with pytest.raises(InputError, match="cannot read file") as e:
        io.read_recording(path)
    assert str(path) in str(e.value)


# --------------------------------------------------------------------------- STO


def test_sto_round_trip_is_exact(tmp_path):
    rec = make_recording(T=40)
    path = tmp_path / "orientations.sto"
    io.write_sto(rec, path)
    lines = path.read_text().splitlines()
    assert lines[1] == "DataType=Quaternion" and "endheader" in lines
    assert lines[lines.index("endheader") + 1].split("\t")[:3] == ["time", "humerus_l_imu", "radius_l_imu"]
    back = io.read_recording(path)
    assert_same(rec, back, raw=False)


def write_sto_text(path: Path, rec: Recording, names: list[str], extra: bool = False) -> Path:
    cols = ["time"] + names + (["pelvis_imu"] if extra else [])
    lines = ["DataRate=100.000000", "DataType=Quaternion", "version=3", "OpenSimVersion=4.1", "endheader",
             "\t".join(cols)]
    for i in range(rec.n_samples):
        cells = [repr(float(rec.time[i]))] + [",".join(map(repr, rec.quat[s][i].tolist())) for s in SENSORS]
        lines.append("\t".join(cells + (["1,0,0,0"] if extra else [])))
    path.write_text("\n".join(lines) + "\n")
    return path


def test_sto_opensim_names_with_ulna_and_extra_columns(tmp_path):
    rec = make_recording(T=8)
    names = ["humerus_l_imu", "ulna_l_imu", "hand_l_imu", "humerus_r_imu", "ulna_r_imu", "hand_r_imu"]
    back = io.read_sto(write_sto_text(tmp_path / "a.sto", rec, names, extra=True))
    assert_same(rec, back, raw=False)


def test_sto_own_names_and_sensor_map(tmp_path):
    rec = make_recording(T=8)
    assert_same(rec, io.read_sto(write_sto_text(tmp_path / "own.sto", rec, list(SENSORS))), raw=False)
    names = ["humerus_l_imu", "radius_l_imu", "my_hand", "humerus_r_imu", "radius_r_imu", "hand_r_imu"]
    path = write_sto_text(tmp_path / "mapped.sto", rec, names)
    assert_same(rec, io.read_recording(path, sensor_map={"my_hand": "left_hand"}), raw=False)


def test_sto_missing_sensor_names_it_and_columns_found(tmp_path):
    rec = make_recording(T=3)
    names = ["humerus_l_imu", "radius_l_imu", "wrist", "humerus_r_imu", "radius_r_imu", "hand_r_imu"]
    path = write_sto_text(tmp_path / "m.sto", rec, names)
    with pytest.raises(InputError, match=r"sensor left_hand .*found: humerus_l_imu, radius_l_imu, wrist") as e:
        io.read_sto(path)
    assert str(path) in str(e.value)


def test_sto_ambiguous_and_bad_sensor_map(tmp_path):
    rec = make_recording(T=3)
    names = ["humerus_l_imu", "radius_l_imu", "hand_l_imu", "humerus_r_imu", "radius_r_imu", "hand_r_imu"]
    path = write_sto_text(tmp_path / "a.sto", rec, names)
    with pytest.raises(InputError, match="both give sensor left_forearm"):
        io.read_sto(path, sensor_map={"hand_l_imu": "left_forearm", "radius_r_imu": "left_forearm"})
    with pytest.raises(InputError, match="not one of"):
        io.read_sto(path, sensor_map={"hand_l_imu": "left_foot"})
    with pytest.raises(InputError, match="'nothere', which is not in the file"):
        io.read_sto(path, sensor_map={"nothere": "left_hand"})


@pytest.mark.parametrize("how, message, row, col", [
    ("no_endheader", "no 'endheader'", None, None),
    ("no_rows", "no data rows", None, None),
    ("three_numbers", "expected 4 comma-separated", 2, "hand_l_imu"),
    ("ragged", "row has 6 cells", 2, None),
    ("text", "not a number: 'x'", 2, "hand_l_imu (y)"),
    ("nan", "NaN", 2, "left_hand_qy"),
])
def test_sto_bad_input(tmp_path, how, message, row, col):
    path = tmp_path / "bad.sto"
    io.write_sto(make_recording(T=4), path)
    lines = path.read_text().splitlines()
    k = lines.index("endheader")
    cells = lines[k + 3].split("\t")  # data row 2; cells[3] is hand_l_imu
    if how == "three_numbers":
        cells[3] = "1,0,0"
    elif how == "ragged":
        cells = cells[:-1]
    elif how in ("text", "nan"):
        cells[3] = "1,0,x,0" if how == "text" else "1,0,nan,0"
    lines[k + 3] = "\t".join(cells)
    if how == "no_endheader":
        del lines[k]
    elif how == "no_rows":
        lines = lines[: k + 2]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=message) as e:
        io.read_recording(path)
    text = str(e.value)
    assert text.startswith(str(path)), text
    if row:
        assert f"row {row}" in text, text
    if col:
        assert f"column '{col}" in text, text


# --------------------------------------------------------------------------- MAT


@pytest.mark.skipif(not REAL_MAT.exists(), reason=f"public qmt recording not present at {REAL_MAT}")
def test_real_qmt_mat():
    rec = io.read_recording(REAL_MAT)
    assert rec.n_samples == 10_000
    assert set(rec.quat) == set(SENSORS)
    assert set(rec.acc) == set(SENSORS) and set(rec.gyr) == set(SENSORS)
    assert rec.time[0] == pytest.approx(40.0) and rec.rate_hz == pytest.approx(100.0, rel=1e-6)
    for s in SENSORS:
        assert rec.quat[s].shape == (10_000, 4) and rec.acc[s].shape == (10_000, 3)
    # At rest-ish the accelerometer reads about g.
    assert 8.0 < np.median(np.linalg.norm(rec.acc["left_hand"], axis=1)) < 11.5


def save_mat(path: Path, rec: Recording, names: dict[str, str] | None = None, drop: str | None = None,
             time_name: str = "t") -> Path:
    rng = np.random.default_rng(5)
    content = {time_name: rec.time, "upper_back": {"quat": rec.quat[SENSORS[0]]}}
    for s in SENSORS:
        fields = {"acc": rng.normal(size=(rec.n_samples, 3)), "gyr": rng.normal(size=(rec.n_samples, 3)),
                  "quat": rec.quat[s]}
        fields.pop(drop, None)
        content[(names or {}).get(s, s)] = fields
    scipy.io.savemat(path, content)
    return path


def test_small_mat_with_own_names(tmp_path):
    rec = make_recording(T=12)
    back = io.read_recording(save_mat(tmp_path / "own.mat", rec, time_name="time"))
    assert_same(rec, back, raw=False)
    assert back.acc["left_hand"].shape == (12, 3) and back.gyr["right_hand"].shape == (12, 3)


def test_mat_sensor_map(tmp_path):
    rec = make_recording(T=5)
    path = save_mat(tmp_path / "m.mat", rec, names={"left_hand": "LH"})
    with pytest.raises(InputError, match=r"sensor left_hand .*'left_hand' or 'hand_left'"):
        io.read_mat(path)
    assert_same(rec, io.read_mat(path, sensor_map={"LH": "left_hand"}), raw=False)


def test_mat_bad_inputs(tmp_path):
    rec = make_recording(T=5)
    corrupt = tmp_path / "corrupt.mat"
    corrupt.write_bytes(b"MATLAB 5.0 MAT-file" + bytes(200))
    with pytest.raises(InputError, match="not a readable MATLAB") as e:
        io.read_recording(corrupt)
    assert str(corrupt) in str(e.value)

    no_time = tmp_path / "no_time.mat"
    scipy.io.savemat(no_time, {"left_hand": {"quat": rec.quat["left_hand"]}})
    with pytest.raises(InputError, match="no time vector 't' or 'time'; variables found: left_hand"):
        io.read_mat(no_time)

    no_quat = save_mat(tmp_path / "no_quat.mat", rec, drop="quat")
    no_quat_no_gyr = tmp_path / "partial.mat"
    content = scipy.io.loadmat(no_quat)
    content["left_hand"] = {"acc": np.zeros((5, 3))}
    scipy.io.savemat(no_quat_no_gyr, {k: v for k, v in content.items() if not k.startswith("__")})
    with pytest.raises(InputError, match=r"column 'left_hand.quat'.*no field 'quat'.*fields: acc") as e:
        io.read_mat(no_quat_no_gyr)
    assert str(no_quat_no_gyr) in str(e.value)

    bad_shape = tmp_path / "shape.mat"
    content = {"t": rec.time, **{s: {"quat": rec.quat[s]} for s in SENSORS}}
    content["hand_left"] = content.pop("left_hand")
    content["hand_left"]["quat"] = rec.quat["left_hand"][:, :3]
    scipy.io.savemat(bad_shape, content)
    with pytest.raises(InputError, match=r"column 'hand_left.quat'.*expected shape \(5, 4\)"):
        io.read_mat(bad_shape)


# --------------------------------------------------------------------------- sensor fusion fallback


def raw_only_csv(tmp_path: Path, T: int, sensor: str = "right_forearm") -> tuple[Path, Recording]:
    rec = make_recording(T=T)
    rec = Recording(time=np.arange(T) / 100.0, quat=rec.quat)
    header, rows = table(rec)
    keep = [j for j, h in enumerate(header) if not h.startswith(sensor + "_q")]
    header = [header[j] for j in keep] + [sensor + x for x in ("_ax", "_ay", "_az", "_gx", "_gy", "_gz")]
    rows = [[r[j] for j in keep] + [0.0, 0.0, 9.81, 0.0, 0.0, 0.0] for r in rows]
    return write_text(tmp_path / "raw.csv", header, rows), rec


def test_fusion_is_called_for_sensors_without_quaternions(tmp_path, monkeypatch):
    calls = []

    def fake(acc, gyr, rate_hz):
        calls.append((acc.copy(), gyr.copy(), rate_hz))
        return np.tile([0.0, 0.0, 0.0, 1.0], (len(acc), 1))

    monkeypatch.setitem(sys.modules, "dualarm.mocap.fusion", types.SimpleNamespace(orientation_from_imu=fake))
    path, rec = raw_only_csv(tmp_path, T=30)
    back = io.read_csv(path)
    (acc, gyr, rate), = calls
    assert acc.shape == gyr.shape == (30, 3) and np.all(acc[:, 2] == 9.81) and rate == pytest.approx(100.0)
    assert np.array_equal(back.quat["right_forearm"], np.tile([0.0, 0.0, 0.0, 1.0], (30, 1)))
    assert np.array_equal(back.quat["left_hand"], rec.quat["left_hand"])
    assert back.acc.keys() == back.gyr.keys() == {"right_forearm"}

    # Same path from a .mat struct without 'quat'.
    back = io.read_mat(save_mat(tmp_path / "raw.mat", make_recording(T=30), drop="quat"))
    assert len(calls) == 1 + len(SENSORS)


def test_fusion_rejects_nan_raw_data_and_bad_time_first(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "dualarm.mocap.fusion",
                        types.SimpleNamespace(orientation_from_imu=lambda a, g, r: pytest.fail("called")))
    path, _ = raw_only_csv(tmp_path, T=6)
    lines = path.read_text().splitlines()
    cells = lines[4].split(",")
    cells[-1] = "nan"  # right_forearm_gz, data row 4
    lines[4] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"row 4, column 'right_forearm_gx..right_forearm_gz'.*gyr is NaN"):
        io.read_csv(path)
    cells = lines[2].split(",")
    cells[0] = "5"  # time jumps ahead then back
    lines[2] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"row 3, column 'time'.*not strictly increasing"):
        io.read_csv(path)


def test_fusion_real_stationary_is_level(tmp_path):
    pytest.importorskip("dualarm.mocap.fusion", reason="dualarm.mocap.fusion not written yet")
    path, _ = raw_only_csv(tmp_path, T=200)
    q = io.read_csv(path).quat["right_forearm"]
    z = Rotation.from_quat(q, scalar_first=True).apply([0.0, 0.0, 1.0])
    tilt = np.degrees(np.arccos(np.clip(z[:, 2], -1.0, 1.0)))
    assert tilt.max() < 2.0
