"""Tests of dualarm.demos and dualarm.constraints: Eq. 12, labels files, segmentation, analysis, plots, CLI."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml

from dualarm.cli.main import main
from dualarm.constraints.analysis import arm_volume_fractions, expert_inside_fractions
from dualarm.constraints.extraction import (combine_ranges, demo_ranges, extract_constraints,
                                            extraction_provenance, segment_masks)
from dualarm.demos.labels import labels_csv_text, read_labels
from dualarm.demos.loading import DemoJoints, load_demo_dir, MappingOptions
from dualarm.demos.segmentation import hand_points, segment_demo, segmentation_agreement
from dualarm.constraints.plots import plot_constraints, plot_expert_inside, plot_volume_fractions, task_phase
from dualarm.constraints.constraint_set import ConstraintSet, default_constraints_path, parse_segments
from dualarm.task import JOINT_COLUMNS, SUBTASKS
from dualarm.demos.formats import DEFAULT_DEMO_DIR, file_sha256
from dualarm.errors import InputError
from dualarm.kinematics import BAXTER_JOINT_LIMITS
from dualarm.mocap.io import write_csv
from dualarm.mocap.synthetic import example_motion, random_mountings, synthetic_recording

LIM = np.concatenate([BAXTER_JOINT_LIMITS, BAXTER_JOINT_LIMITS])

# --------------------------------------------------------------------------- hand-made demonstrations

DT = 0.1
TIME = np.round(np.arange(101) * DT, 10)                  # 0 .. 10 s
#: Per arm: reach, grasp, align windows (s); gaps before reach and after align.
WINDOWS = np.array([[[1.0, 3.0], [3.0, 5.0], [5.0, 8.0]],
                    [[1.5, 4.0], [4.0, 6.0], [6.0, 9.0]]])
BASE = 0.1 * np.arange(14)                                 # inside every Baxter limit


def planted(m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Demo m: constant BASE with one planted low and one high value per (sub-task, joint).

    Returns q (T, 14) and the planted lows and highs (3, 14), and puts far-out values in the
    gaps (outside every sub-task), which Eq. 12 must ignore.
    """
    q = np.tile(BASE, (TIME.size, 1))
    lows = np.empty((3, 14))
    highs = np.empty((3, 14))
    for k in range(14):
        arm = k // 7
        for n in range(3):
            s, e = WINDOWS[arm, n]
            i_lo = int(round((s + 0.3 * (e - s)) / DT))
            i_hi = int(round((s + 0.6 * (e - s)) / DT))
            lows[n, k] = BASE[k] - (0.01 + 0.003 * m + 0.05 * n + 0.001 * k)
            highs[n, k] = BASE[k] + (0.02 + 0.004 * ((m + k) % 3) + 0.03 * n)
            q[i_lo, k] = lows[n, k]
            q[i_hi, k] = highs[n, k]
    q[int(0.5 / DT)] = BASE - 0.9      # before both arms' reach
    q[int(9.5 / DT)] = BASE + 0.9      # after both arms' align
    return q, lows, highs


def handmade(count: int = 3):
    demos, lows, highs = [], [], []
    for m in range(count):
        q, lo, hi = planted(m)
        demos.append(DemoJoints(f"d{m}", TIME, q))
        lows.append(lo)
        highs.append(hi)
    windows = {d.name: WINDOWS for d in demos}
    return demos, windows, np.stack(lows), np.stack(highs)


@pytest.mark.parametrize("spec", ["reach+grasp+align", "reach+grasp,align", "reach,grasp,align", "reach,grasp+align"])
def test_eq12_planted_extremes(spec):
    demos, windows, lows, highs = handmade()
    cs = extract_constraints(demos, windows, spec)
    groups = parse_segments(spec)
    assert len(cs.segments) == len(groups)
    for seg, group in zip(cs.segments, groups):
        idx = [SUBTASKS.index(n) for n in group]
        assert seg.subtasks == group
        # Eq. 12 by hand: the smallest planted low and the largest planted high over demos and sub-tasks.
        np.testing.assert_allclose(seg.lower, lows[:, idx].min(axis=(0, 1)), rtol=0, atol=1e-15)
        np.testing.assert_allclose(seg.upper, highs[:, idx].max(axis=(0, 1)), rtol=0, atol=1e-15)
    assert cs.name == ("single" if len(groups) == 1 else "multi")


def test_eq12_each_arm_uses_its_own_windows():
    # A spike in a right-arm joint at t = 3.5 s: the left arm is in grasp then, the right arm in reach.
    q = np.tile(BASE, (TIME.size, 1))
    q[35, 7] = BASE[7] + 0.3
    q[35, 0] = BASE[0] + 0.3
    cs = extract_constraints([DemoJoints("d", TIME, q)], {"d": WINDOWS}, "reach,grasp,align")
    reach, grasp, align = cs.segments
    assert reach.upper[7] == pytest.approx(BASE[7] + 0.3) and grasp.upper[7] == pytest.approx(BASE[7])
    assert grasp.upper[0] == pytest.approx(BASE[0] + 0.3) and reach.upper[0] == pytest.approx(BASE[0])
    assert align.upper[7] == pytest.approx(BASE[7]) and align.upper[0] == pytest.approx(BASE[0])


def test_boundary_sample_belongs_to_both_sub_tasks():
    q = np.tile(BASE, (TIME.size, 1))
    q[30, 2] = BASE[2] - 0.2                  # t = 3.0 s: left arm's reach/grasp boundary
    cs = extract_constraints([DemoJoints("d", TIME, q)], {"d": WINDOWS}, "reach,grasp,align")
    assert cs.segments[0].lower[2] == pytest.approx(BASE[2] - 0.2)
    assert cs.segments[1].lower[2] == pytest.approx(BASE[2] - 0.2)
    assert cs.segments[2].lower[2] == pytest.approx(BASE[2])


def test_segment_masks_and_gaps():
    w = WINDOWS.copy()
    w[0, 1] = [3.5, 5.0]                      # a gap 3.0-3.5 s for the left arm
    masks = segment_masks(TIME, w, parse_segments("reach+grasp,align"))
    assert masks.shape == (2, 2, TIME.size)
    left_c2 = TIME[masks[0, 0]]
    assert left_c2.min() == pytest.approx(1.0) and left_c2.max() == pytest.approx(5.0)
    assert not np.any((left_c2 > 3.0 + 1e-9) & (left_c2 < 3.5 - 1e-9))
    assert np.array_equal(TIME[masks[1, 1]], TIME[(TIME >= 6.0 - 1e-9) & (TIME <= 9.0 + 1e-9)])


def test_combine_ranges_is_min_of_lows_and_max_of_highs():
    lo = np.array([[[0.0, 1.0]], [[-1.0, 2.0]], [[0.5, 0.5]]])        # (M=3, S=1, 2)
    hi = np.array([[[3.0, 1.5]], [[2.0, 4.0]], [[5.0, 0.7]]])
    a, b = combine_ranges(lo, hi)
    assert a.tolist() == [[-1.0, 0.5]] and b.tolist() == [[5.0, 4.0]]


def test_percentile_ignores_an_outlying_sample():
    t = np.arange(202) * 0.01
    ramp = np.linspace(0.0, 1.0, 202)
    q = np.tile(BASE, (t.size, 1))
    q[:, 3] = 0.5 + ramp                        # e1 from 0.5 to 1.5 rad
    q[100, 3] = 2.5                             # one glitch
    w = np.tile(np.array([[0.0, 0.5], [0.5, 1.0], [1.0, 2.01]]), (2, 1, 1))
    plain = extract_constraints([DemoJoints("d", t, q)], {"d": w}, "reach+grasp+align")
    robust = extract_constraints([DemoJoints("d", t, q)], {"d": w}, "reach+grasp+align", percentile=2.0)
    assert plain.segments[0].upper[3] == pytest.approx(2.5)
    assert 1.4 < robust.segments[0].upper[3] < 1.5
    assert 0.5 < robust.segments[0].lower[3] < 0.6
    lo, hi = demo_ranges(q, segment_masks(t, w, (SUBTASKS,)), 0.0)
    assert lo[0, 3] == pytest.approx(0.5) and hi[0, 3] == pytest.approx(2.5)


def test_margin_widens_and_clips_to_baxter_limits():
    demos, windows, lows, highs = handmade()
    base = extract_constraints(demos, windows, "reach+grasp+align")
    wide = extract_constraints(demos, windows, "reach+grasp+align", margin=0.05)
    np.testing.assert_allclose(wide.segments[0].lower, np.maximum(base.segments[0].lower - 0.05, LIM[:, 0]))
    np.testing.assert_allclose(wide.segments[0].upper, base.segments[0].upper + 0.05)
    huge = extract_constraints(demos, windows, "reach+grasp+align", margin=10.0)
    np.testing.assert_array_equal(huge.segments[0].lower, LIM[:, 0])
    np.testing.assert_array_equal(huge.segments[0].upper, LIM[:, 1])
    assert huge.volume_fraction()[0] == pytest.approx(1.0)


@pytest.mark.parametrize("kwargs, field", [({"percentile": 50.0}, "percentile"), ({"percentile": -1.0}, "percentile"),
                                           ({"margin": -0.1}, "margin"), ({"margin": float("nan")}, "margin")])
def test_bad_options(kwargs, field):
    demos, windows, _, _ = handmade(1)
    with pytest.raises(InputError, match=field):
        extract_constraints(demos, windows, **kwargs)


def test_bad_segment_specs_and_missing_inputs():
    demos, windows, _, _ = handmade(1)
    for spec in ("reach+grasp", "align,reach+grasp", "reach+grip,align", ""):
        with pytest.raises(InputError, match="segments"):
            extract_constraints(demos, windows, spec)
    with pytest.raises(InputError, match="no demonstrations"):
        extract_constraints([], windows)
    with pytest.raises(InputError, match="'d0' has no labels"):
        extract_constraints(demos, {})
    w = WINDOWS.copy()
    w[1, 1] = [4.01, 4.05]                          # no sample between two 0.1 s samples
    with pytest.raises(InputError, match=r"demo 'd0', right arm: segment 2 has no samples"):
        extract_constraints(demos, {"d0": w}, "reach,grasp,align")


# --------------------------------------------------------------------------- labels files

def write(tmp_path: Path, text: str, name: str = "labels.csv") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def full_labels(rows_for=("left", "right"), demo="demo_a", times=((1, 2), (2, 3), (3, 4))) -> str:
    lines = ["demo,arm,subtask,start_s,end_s"]
    for arm in rows_for:
        for sub, (s, e) in zip(SUBTASKS, times):
            lines.append(f"{demo},{arm},{sub},{s},{e}")
    return "\n".join(lines) + "\n"


def test_labels_round_trip(tmp_path):
    windows = {"x": WINDOWS + 0.12345, "y": WINDOWS * 1.5}
    path = write(tmp_path, labels_csv_text(windows))
    got = read_labels(path)
    assert list(got) == ["x", "y"]
    for name in windows:
        np.testing.assert_allclose(got[name].windows, windows[name], atol=5e-5)
        assert got[name].rows.min() >= 1
    assert path.read_text().splitlines()[0] == "demo,arm,subtask,start_s,end_s"


def test_labels_both_arms_and_optional_arm_column(tmp_path):
    both = read_labels(write(tmp_path, full_labels(rows_for=("both",))))
    no_arm = read_labels(write(tmp_path, "demo,subtask,start_s,end_s\n" + "".join(
        f"demo_a,{s},{a},{b}\n" for s, (a, b) in zip(SUBTASKS, ((1, 2), (2, 3), (3, 4)))), "b.csv"))
    expected = np.tile(np.array([[1.0, 2.0], [2.0, 3.0], [3.0, 4.0]]), (2, 1, 1))
    np.testing.assert_array_equal(both["demo_a"].windows, expected)
    np.testing.assert_array_equal(no_arm["demo_a"].windows, expected)
    # A gap between sub-tasks is allowed.
    gap = read_labels(write(tmp_path, full_labels(times=((1, 2), (2.5, 3), (3, 4))), "c.csv"))
    assert gap["demo_a"].windows[0, 1, 0] == 2.5


BAD_LABELS = [
    ("", r"empty labels file"),
    ("demo,arm,subtask,start_s,end_s\n", r"no label rows"),
    ("demo,arm,subtask,start_s\ndemo_a,left,reach,1\n", r"column 'end_s': missing column"),
    ("demo,arm,subtask,start_s,end_s\ndemo_a,left,reach,1\n", r"row 1: row has 4 cells, the header 5"),
    (full_labels().replace("left,grasp", "left,grab"), r"row 2, column 'subtask': unknown sub-task 'grab'"),
    (full_labels().replace("right,reach", "middle,reach"), r"row 4, column 'arm': unknown arm 'middle'"),
    (full_labels().replace("reach,1,2", "reach,one,2", 1), r"row 1, column 'start_s': expected a number"),
    (full_labels().replace("reach,1,2", "reach,-1,2", 1), r"row 1, column 'start_s': time before the recording"),
    (full_labels().replace("reach,1,2", "reach,1,nan", 1), r"row 1, column 'end_s': expected a finite number"),
    (full_labels().replace("align,3,4", "align,4,3", 1), r"row 3, column 'end_s': start_s 4 is not before end_s 3"),
    (full_labels() + "demo_a,left,grasp,2,3\n", r"grasp of the left arm is labelled twice \(rows 2 and 7\)"),
    (full_labels() + "demo_a,both,align,3,4\n", r"align of the left arm is labelled twice"),
    ("\n".join(full_labels().splitlines()[:-1]) + "\n", r"demo 'demo_a': no align label for the right arm"),
    (full_labels(times=((1, 2.5), (2, 3), (3, 4))), r"row 2, column 'start_s': demo 'demo_a', left arm: grasp "
                                                    r"\(2-3 s\) overlaps reach \(1-2.5 s\)"),
    (full_labels(times=((3, 4), (1, 2), (4, 5))), r"grasp \(1-2 s\) starts before reach"),
    ("demo,arm,subtask,start_s,end_s\n,left,reach,1,2\n", r"row 1, column 'demo': empty demo name"),
]


@pytest.mark.parametrize("text, message", BAD_LABELS)
def test_bad_labels_are_named(tmp_path, text, message):
    path = write(tmp_path, text)
    with pytest.raises(InputError) as info:
        read_labels(path)
    assert str(info.value).startswith(str(path))
    assert re.search(message, str(info.value)), str(info.value)


def test_labels_file_missing_or_folder(tmp_path):
    with pytest.raises(InputError, match="labels file not found"):
        read_labels(tmp_path / "nope.csv")
    with pytest.raises(InputError, match="is a directory"):
        read_labels(tmp_path)


# --------------------------------------------------------------------------- demo folders

@pytest.fixture(scope="module")
def small_dir(tmp_path_factory):
    """Two short synthetic recordings (4 s at 50 Hz) and labels for them."""
    d = tmp_path_factory.mktemp("demos")
    rng = np.random.default_rng(5)
    for name in ("a", "b"):
        t, q = example_motion(duration_s=4.0, rate_hz=50.0, calib_s=1.0)
        write_csv(synthetic_recording(t, q, mountings=random_mountings(rng)), d / f"{name}.csv")
    labels = {n: np.tile(np.array([[1.2, 2.0], [2.0, 2.5], [2.5, 3.5]]), (2, 1, 1)) for n in ("a", "b")}
    (d / "labels.csv").write_text(labels_csv_text(labels))
    return d


def test_load_demo_dir_maps_and_checks(small_dir):
    demos, labels = load_demo_dir(small_dir)
    assert [d.name for d in demos] == ["a", "b"] and set(labels) == {"a", "b"}
    d = demos[0]
    assert d.q.shape == (200, 14) and d.time[0] == 0.0
    assert np.all(d.q >= LIM[:, 0]) and np.all(d.q <= LIM[:, 1])
    assert len(d.sha256) == 64 and d.sha256 == file_sha256(small_dir / "a.csv")
    t, q = example_motion(duration_s=4.0, rate_hz=50.0, calib_s=1.0)
    raw = load_demo_dir(small_dir, options=MappingOptions(lowpass_hz=0))[0][0]
    np.testing.assert_allclose(raw.q, np.clip(q, LIM[:, 0], LIM[:, 1]), atol=1e-6)


def test_demo_dir_errors(small_dir, tmp_path):
    labels = read_labels(small_dir / "labels.csv")
    text = labels_csv_text({n: lab.windows for n, lab in labels.items()})
    # A labelled demo without a recording.
    bad = write(tmp_path, text + "c,both,reach,1,2\nc,both,grasp,2,3\nc,both,align,3,4\n", "extra.csv")
    with pytest.raises(InputError, match=r"extra.csv, row 13, column 'demo': demo 'c' has no recording"):
        load_demo_dir(small_dir, bad)
    # A recording without labels.
    only_a = write(tmp_path, "\n".join(line for line in text.splitlines() if not line.startswith("b,")) + "\n",
                   "only_a.csv")
    with pytest.raises(InputError, match=r"recording b.csv has no labels"):
        load_demo_dir(small_dir, only_a)
    # A window after the end of the recording (3.98 s long).
    late = write(tmp_path, text.replace("a,right,align,2.5000,3.5000", "a,right,align,2.5000,4.5000"), "late.csv")
    with pytest.raises(InputError, match=r"late.csv, row 6, column 'end_s': demo 'a', right arm, align: end_s 4.5 "
                                         r"is after the end of the recording \(3.98 s\)"):
        load_demo_dir(small_dir, late)
    with pytest.raises(InputError, match="demonstration folder not found"):
        load_demo_dir(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no recordings"):
        load_demo_dir(tmp_path / "empty")


# --------------------------------------------------------------------------- files and defaults

def test_extracted_file_round_trip_with_provenance(tmp_path, small_dir):
    demos, labels = load_demo_dir(small_dir)
    prov = extraction_provenance(demos, small_dir / "labels.csv", "labels file", MappingOptions(),
                                    "reach+grasp,align", 1.0, 0.02)
    cs = extract_constraints(demos, labels, "reach+grasp,align", percentile=1.0, margin=0.02, provenance=prov)
    path = tmp_path / "c.yaml"
    cs.save(path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")             # bounds inside the limits: no clipping warning
        back = ConstraintSet.load(path)
    assert back == cs and back.name == "multi"
    p = back.provenance
    assert [d["file"] for d in p["demos"]] == ["a.csv", "b.csv"]
    assert p["demos"][1]["sha256"] == file_sha256(small_dir / "b.csv")
    assert p["labels"]["sha256"] == file_sha256(small_dir / "labels.csv")
    assert p["options"] == {"segments": "reach+grasp,align", "percentile": 1.0, "margin_rad": 0.02,
                            "lowpass_hz": 6.0, "calib_seconds": 1.0, "calib_start": 0.0, "calib_pose": "npose",
                            "heading": "auto"}
    data = yaml.safe_load(path.read_text())
    assert data["joints"] == list(JOINT_COLUMNS) and data["units"] == "rad" and data["schema_version"] == 1


@pytest.mark.parametrize("change, message", [
    (lambda p: p["demos"].__setitem__(0, {"file": "a.csv", "sha256": "abc"}), r"provenance.demos\[0\].sha256: "
                                                                              r"expected 64 lower-case hex"),
    (lambda p: p["demos"].__setitem__(1, {"file": 3, "sha256": "0" * 64}), r"provenance.demos\[1\].file"),
    (lambda p: p["labels"].update(sha256="F" * 64), r"provenance.labels.sha256"),
])
def test_bad_provenance_is_named(tmp_path, change, message):
    data = yaml.safe_load(default_constraints_path("multi").read_text())
    change(data["provenance"])
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(InputError, match=message):
        ConstraintSet.load(path)


def test_default_constraints_paths():
    for condition, n in (("single", 1), ("multi", 2)):
        path = default_constraints_path(condition)
        assert path.is_file() and path.parent.parent.name == "data"
        cs = ConstraintSet.load(path)
        assert cs.name == condition and len(cs.segments) == n
        assert len(cs.provenance["demos"]) == 10
    with pytest.raises(ValueError, match="single, multi"):
        default_constraints_path("none")


@pytest.fixture(scope="module")
def shipped():
    """The shipped demonstrations mapped with the default options, with their gripper events."""
    return load_demo_dir(DEFAULT_DEMO_DIR, with_grip=True)


def test_shipped_constraint_files_come_from_the_shipped_demos(shipped):
    demos, labels = shipped
    for condition, spec in (("single", "reach+grasp+align"), ("multi", "reach+grasp,align")):
        cs = ConstraintSet.load(default_constraints_path(condition))
        again = extract_constraints(demos, labels, spec)
        for a, b in zip(cs.segments, again.segments):
            np.testing.assert_allclose(a.lower, b.lower, atol=1e-9)
            np.testing.assert_allclose(a.upper, b.upper, atol=1e-9)
        hashes = {d["file"]: d["sha256"] for d in cs.provenance["demos"]}
        assert hashes == {Path(d.source).name: d.sha256 for d in demos}


# --------------------------------------------------------------------------- automatic segmentation

@pytest.mark.parametrize("use_grip", [True, False])
def test_automatic_segmentation_agrees_with_labels(shipped, use_grip):
    demos, labels = shipped
    errors, agree = [], []
    for d in demos:
        assert d.grip is not None and d.grip.shape == (len(d.time), 2)
        auto = segment_demo(d.time, d.q, d.grip if use_grip else None, calib_end_s=1.0, demo=d.name)
        r = segmentation_agreement(d.time, auto, labels[d.name].windows)
        errors.append(r["boundary_error_s"])
        agree.append(r["frame_agreement"])
    errors = np.stack(errors)
    # reach start, grasp start and align start within a tenth of a second on average ...
    assert np.all(errors[..., :3].mean(axis=(0, 1)) < 0.1)
    assert np.all(errors[..., :3].max(axis=(0, 1)) < 0.2)
    # ... and most samples given the same sub-task.
    assert np.mean(agree) > 0.8


def test_segmentation_errors_name_the_demo(shipped):
    d = shipped[0][0]
    with pytest.raises(InputError, match=r"demo 'demo_00', left arm: the gripper never closes"):
        segment_demo(d.time, d.q, np.zeros_like(d.grip), demo="demo_00")
    still = np.tile(d.q[0], (len(d.time), 1))
    with pytest.raises(InputError, match=r"demo 'x', left arm: no pause before the reach"):
        segment_demo(d.time, still, None, demo="x")
    # The hand goes down to the box and stays there.
    low = int(np.argmin(hand_points(d.q)[:, 0, 2]))
    stays = d.q.copy()
    stays[low:] = stays[low]
    with pytest.raises(InputError, match=r"demo 'y', left arm: the hand never rises 0.02 m"):
        segment_demo(d.time, stays, None, demo="y")


def test_agreement_of_identical_and_shifted_windows():
    same = segmentation_agreement(TIME, WINDOWS, WINDOWS)
    assert np.all(same["boundary_error_s"] == 0) and np.all(same["frame_agreement"] == 1)
    shifted = WINDOWS.copy()
    shifted[:, 1, 0] += 0.5
    shifted[:, 0, 1] += 0.5
    r = segmentation_agreement(TIME, shifted, WINDOWS)
    np.testing.assert_allclose(r["boundary_error_s"], [[0, 0.5, 0, 0]] * 2)
    # 5 of the 70 (left) and 75 (right) labelled samples change sub-task.
    np.testing.assert_allclose(r["frame_agreement"], [1 - 5 / 70, 1 - 5 / 75])


# --------------------------------------------------------------------------- analysis

def test_width_and_volume_fractions():
    full = ConstraintSet.full_range()
    np.testing.assert_allclose(full.width_fractions(), 1.0)
    np.testing.assert_allclose(arm_volume_fractions(full), 1.0)
    span = LIM[:, 1] - LIM[:, 0]
    half = ConstraintSet.from_groups({"reach+grasp": (LIM[:, 0] + 0.25 * span, LIM[:, 0] + 0.75 * span),
                                      "align": (LIM[:, 0], LIM[:, 0] + np.r_[[0.1] * 7, [1.0] * 7] * span)})
    np.testing.assert_allclose(half.width_fractions(), [[0.5] * 14, [0.1] * 7 + [1.0] * 7])
    np.testing.assert_allclose(arm_volume_fractions(half), [[0.5 ** 7, 0.5 ** 7], [1e-7, 1.0]])
    np.testing.assert_allclose(half.volume_fraction(), [0.5 ** 14, 1e-7])


def test_expert_inside_fractions_hand_counted():
    lo = np.zeros(14)
    cs = ConstraintSet.from_groups({"reach+grasp": (lo, np.full(14, 1.0)), "align": (lo, np.full(14, 0.5))})
    q = np.array([np.full(14, 0.7), np.full(14, 0.7), np.full(14, 0.2), np.full(14, 1.2)])
    q[2, 3] = -0.1
    sub = np.array([[0, 2], [2, 2], [1, 0], [2, 1]])
    r = expert_inside_fractions(cs, q, sub)
    # Left arm: rows 0, 2 in reach+grasp (0.7 in, 0.2 in except joint 3) and rows 1, 3 in align (0.7, 1.2 out).
    # Right arm: rows 2, 3 in reach+grasp (0.2 in, 1.2 out) and rows 0, 1 in align (0.7 out twice).
    expected_left_c2 = np.ones(7)
    expected_left_c2[3] = 0.5
    np.testing.assert_allclose(r.fraction[0, :7], expected_left_c2)
    np.testing.assert_allclose(r.fraction[1, :7], 0.0)
    np.testing.assert_allclose(r.fraction[0, 7:], 0.5)
    np.testing.assert_allclose(r.fraction[1, 7:], 0.0)
    np.testing.assert_array_equal(r.count, [[2, 2], [2, 2]])
    np.testing.assert_allclose(r.all_joints, [[0.5, 0.5], [0.0, 0.0]])


# --------------------------------------------------------------------------- figures

def test_task_phase():
    ph = task_phase(TIME, WINDOWS)
    assert np.isnan(ph[0, TIME < 1.0 - 1e-9]).all() and np.isnan(ph[0, TIME > 8.0 + 1e-9]).all()
    assert ph[0, 20] == pytest.approx(0.5) and ph[0, 40] == pytest.approx(1.5) and ph[1, 75] == pytest.approx(2.5)


def test_figures_are_written(tmp_path):
    demos, windows, _, _ = handmade(2)
    cs = extract_constraints(demos, windows)
    single = extract_constraints(demos, windows, "reach+grasp+align")
    paths = [plot_constraints(cs, demos, windows, tmp_path / "c.png"),
             plot_volume_fractions({"single": single, "multi": cs}, tmp_path / "v.png"),
             plot_expert_inside({"multi": (cs, np.full((2, 14), 0.5))}, tmp_path / "e.png")]
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 10_000
    assert sorted(x.name for x in tmp_path.iterdir()) == ["c.png", "e.png", "v.png"]   # no temporary files left


# --------------------------------------------------------------------------- command line

def test_cli_extract_plot_analyze(tmp_path, small_dir, capsys):
    out = tmp_path / "c.yaml"
    assert main(["constraints", "extract", str(small_dir), "--segments", "reach+grasp+align", "--margin", "0.01",
                 "-o", str(out), "-q"]) == 0
    cs = ConstraintSet.load(out)
    assert cs.name == "single" and cs.provenance["options"]["margin_rad"] == 0.01
    fig = tmp_path / "fig.png"
    assert main(["constraints", "plot", str(out), "--demos", str(small_dir), "-o", str(fig)]) == 0
    assert fig.stat().st_size > 10_000
    capsys.readouterr()
    assert main(["constraints", "analyze", str(default_constraints_path("single")),
                 str(default_constraints_path("multi")), "--episodes", "2", "-q", "-o", str(tmp_path / "an")]) == 0
    text = capsys.readouterr().out
    assert "success rate 1.000" in text and "multi: segment 2 (align)" in text and "inside %" in text
    assert {p.name for p in (tmp_path / "an").iterdir()} == {"constraints_volume_fractions.png",
                                                             "constraints_expert_inside.png"}


def test_cli_segment_reports_agreement(tmp_path, capsys):
    out = tmp_path / "auto.csv"
    assert main(["demos", "segment", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert re.search(r"^mean +[\d. ]+\(both arms\) +\d+\.\d%$", text, re.M), text
    auto = read_labels(out)
    assert sorted(auto) == [f"demo_{k:02d}" for k in range(10)]


@pytest.mark.parametrize("argv, message", [
    (["--labels", "{bad}"], r"row 2, column 'subtask': unknown sub-task 'grab'"),
    (["--segments", "reach,align"], r"segments 'reach,align'"),
    (["--percentile", "60"], None),
    (["--labels", "{missing}"], r"labels file not found"),
])
def test_cli_extract_errors_write_nothing(tmp_path, small_dir, capsys, argv, message):
    bad = write(tmp_path, (small_dir / "labels.csv").read_text().replace("a,left,grasp", "a,left,grab"), "bad.csv")
    argv = [a.replace("{bad}", str(bad)).replace("{missing}", str(tmp_path / "none.csv")) for a in argv]
    out = tmp_path / "c.yaml"
    if message is None:                              # argparse rejects the value
        with pytest.raises(SystemExit) as info:
            main(["constraints", "extract", str(small_dir), *argv, "-o", str(out)])
        assert info.value.code == 2
        assert "must be in [0, 50)" in capsys.readouterr().err
    else:
        assert main(["constraints", "extract", str(small_dir), *argv, "-o", str(out), "-q"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and err.startswith("dualarm: error: ")
        assert re.search(message, err), err
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == ["bad.csv"]


def test_help_on_every_new_command(capsys):
    for argv in (["demos", "--help"], ["demos", "generate", "--help"], ["demos", "segment", "--help"],
                 ["constraints", "--help"], ["constraints", "extract", "--help"], ["constraints", "plot", "--help"],
                 ["constraints", "analyze", "--help"]):
        with pytest.raises(SystemExit) as info:
            main(argv)
        assert info.value.code == 0
        assert "usage: dualarm" in capsys.readouterr().out
