"""Tests of dualarm.constraints: guide reward (Eq. 16), lookups, validation, YAML files."""

from __future__ import annotations

import os
import re
import warnings

import numpy as np
import pytest
import yaml

from dualarm.constraints import constraint_set as C
from dualarm.constraints.constraint_set import ConstraintSegment, ConstraintSet, DEFAULT_C0, parse_segments
from dualarm.task import JOINT_COLUMNS, SUBTASKS
from dualarm.errors import InputError
from dualarm.kinematics import BAXTER_JOINT_LIMITS

LIM_LO = np.concatenate([BAXTER_JOINT_LIMITS[:, 0]] * 2)
LIM_HI = np.concatenate([BAXTER_JOINT_LIMITS[:, 1]] * 2)

# C2 (reach+grasp): left arm [-0.5, 0.5], right arm [-0.2, 0.2] on every joint.
C2_LO = np.array([-0.5] * 7 + [-0.2] * 7)
C2_HI = np.array([0.5] * 7 + [0.2] * 7)
# C3 (align): left arm [0, 1], right arm [0.3, 1.3] on every joint.
C3_LO = np.array([0.0] * 7 + [0.3] * 7)
C3_HI = np.array([1.0] * 7 + [1.3] * 7)


def two_segments(**kw) -> ConstraintSet:
    return ConstraintSet.from_groups({"reach+grasp": (C2_LO, C2_HI), "align": (C3_LO, C3_HI)}, name="C2C3", **kw)


def bounds(seed: int = 0):
    """Random valid (14,) lower/upper inside Baxter's limits with awkward floats."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(LIM_LO, LIM_HI)
    b = rng.uniform(LIM_LO, LIM_HI)
    return np.minimum(a, b), np.maximum(a, b)


# --------------------------------------------------------------------------- constants

def test_joint_columns_left_first():
    assert JOINT_COLUMNS[:7] == ("left_s0", "left_s1", "left_e0", "left_e1", "left_w0", "left_w1", "left_w2")
    assert JOINT_COLUMNS[7:] == ("right_s0", "right_s1", "right_e0", "right_e1", "right_w0", "right_w1", "right_w2")
    assert SUBTASKS == ("reach", "grasp", "align")
    assert DEFAULT_C0 == (0.01, 0.01, 0.05)


# --------------------------------------------------------------------------- guide reward

# Left arm q vs C2 left [-0.5, 0.5]: 0.5 in (boundary), 0.6 out, -0.5 in (boundary), -0.51 out,
#   0 in, 0.2 in, 0.9 out                                      -> 4 in, 3 out
# Left arm q vs C3 left [0, 1]: in (0.5), in (0.6), out (-0.5), out (-0.51), in (0, boundary),
#   in (0.2), in (0.9)                                         -> 5 in, 2 out
# Right arm q vs C2 right [-0.2, 0.2]: 0.2 in (boundary), 0.3 out, 1.3 out, -0.2 in (boundary),
#   0.0 in, -1.0 out, 0.21 out                                 -> 3 in, 4 out
# Right arm q vs C3 right [0.3, 1.3]: out, in (0.3, boundary), in (1.3, boundary), out, out,
#   out, out                                                   -> 2 in, 5 out
Q = np.array([0.5, 0.6, -0.5, -0.51, 0.0, 0.2, 0.9,
              0.2, 0.3, 1.3, -0.2, 0.0, -1.0, 0.21])
IN_LEFT_C2 = [1, 0, 1, 0, 1, 1, 0]
IN_LEFT_C3 = [1, 1, 0, 0, 1, 1, 1]
IN_RIGHT_C2 = [1, 0, 0, 1, 1, 0, 0]
IN_RIGHT_C3 = [0, 1, 1, 0, 0, 0, 0]
C0 = (0.01, 0.02, 0.05)


def test_inside_hand_placed_q():
    cs = two_segments()
    got = cs.inside(Q, 0, 2)  # left reach -> C2, right align -> C3
    assert got.dtype == bool
    assert got.tolist() == [bool(x) for x in IN_LEFT_C2 + IN_RIGHT_C3]
    got = cs.inside(Q, "align", "grasp")  # left C3, right C2
    assert got.tolist() == [bool(x) for x in IN_LEFT_C3 + IN_RIGHT_C2]


@pytest.mark.parametrize("sl, sr, expected", [
    # left reach (C2, c0 0.01): 4 in 3 out; right align (C3, c0 0.05): 2 in 5 out
    (0, 2, (0.01 * (4 - 3), 0.05 * (2 - 5))),
    # left align (C3, 0.05): 5 in 2 out; right grasp (C2, 0.02): 3 in 4 out
    (2, 1, (0.05 * (5 - 2), 0.02 * (3 - 4))),
    # both grasp (C2, 0.02)
    (1, 1, (0.02 * (4 - 3), 0.02 * (3 - 4))),
    # names work like indices
    ("reach", "align", (0.01 * (4 - 3), 0.05 * (2 - 5))),
])
def test_guide_reward_hand_computed(sl, sr, expected):
    r = two_segments().guide_reward(Q, sl, sr, C0)
    assert r.shape == (2,)
    np.testing.assert_allclose(r, expected, rtol=0, atol=1e-15)


def test_guide_reward_default_c0_and_extremes():
    cs = two_segments()
    inside_all = np.r_[np.zeros(7), np.zeros(7)]  # inside C2 for both arms
    np.testing.assert_allclose(cs.guide_reward(inside_all, 0, 0), [0.07, 0.07], atol=1e-15)
    # left arm in align with C3 left [0, 1]: q = 0 is the boundary, inside; right 0 < 0.3 outside.
    np.testing.assert_allclose(cs.guide_reward(inside_all, 2, 2), [0.35, -0.35], atol=1e-15)
    outside_all = np.full(14, 5.0)
    np.testing.assert_allclose(cs.guide_reward(outside_all, 1, 2, C0), [-0.14, -0.35], atol=1e-15)


def test_guide_reward_list_input_and_numpy_int_subtasks():
    cs = two_segments()
    r = cs.guide_reward(Q.tolist(), np.int64(2), np.int32(1), C0)
    np.testing.assert_allclose(r, (0.05 * 3, 0.02 * -1), atol=1e-15)


def test_multi_segment_lookup_tables():
    cs = two_segments()
    assert cs.segment_of_subtask.tolist() == [0, 0, 1]
    np.testing.assert_array_equal(cs.lower_by_subtask, np.stack([C2_LO, C2_LO, C3_LO]))
    np.testing.assert_array_equal(cs.upper_by_subtask, np.stack([C2_HI, C2_HI, C3_HI]))
    for k, name in enumerate(SUBTASKS):
        lo, hi = cs.bounds(name)
        lo_i, hi_i = cs.bounds(k)
        np.testing.assert_array_equal(lo, lo_i)
        np.testing.assert_array_equal(hi, hi_i)
    np.testing.assert_array_equal(cs.bounds("grasp")[1], C2_HI)
    np.testing.assert_array_equal(cs.bounds("align")[0], C3_LO)
    assert cs.segments[0].subtasks == ("reach", "grasp")
    assert cs.segments[1].subtasks == ("align",)


def test_three_segment_lookup():
    lo, hi = bounds(1)
    cs = ConstraintSet.from_groups([("reach", lo, hi), (("grasp",), lo - 0.01, hi), ("align", lo, hi + 0.01)])
    assert cs.segment_of_subtask.tolist() == [0, 1, 2]
    np.testing.assert_array_equal(cs.bounds(1)[0], lo - 0.01)
    np.testing.assert_array_equal(cs.bounds(2)[1], hi + 0.01)


def test_batch_shape_matches_single_calls():
    cs = two_segments()
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.5, 1.5, (4, 5, 14))
    r = cs.guide_reward(q, 0, 2, C0)
    assert r.shape == (4, 5, 2)
    assert cs.inside(q, 0, 2).shape == (4, 5, 14)
    single = np.array([[cs.guide_reward(q[i, j], 0, 2, C0) for j in range(5)] for i in range(4)])
    np.testing.assert_allclose(r, single, atol=1e-15)
    # Outcomes vary over the batch (else the comparison above would be weak).
    assert len(np.unique(r[..., 0])) > 2


def test_batch_per_row_subtasks():
    cs = two_segments()
    q = np.stack([Q, Q, Q])
    sl = np.array([0, 2, 1])
    sr = np.array([2, 1, 1])
    r = cs.guide_reward(q, sl, sr, C0)
    assert r.shape == (3, 2)
    for i in range(3):
        np.testing.assert_allclose(r[i], cs.guide_reward(Q, int(sl[i]), int(sr[i]), C0), atol=1e-15)
    np.testing.assert_allclose(r[1], (0.05 * 3, 0.02 * -1), atol=1e-15)
    names = np.array(["reach", "align", "grasp"])
    np.testing.assert_array_equal(cs.guide_reward(q, names, sr, C0), r)


def test_guide_reward_c0_array_input():
    cs = two_segments()
    np.testing.assert_allclose(cs.guide_reward(Q, 1, 2, np.array(C0)), cs.guide_reward(Q, 1, 2, C0))
    np.testing.assert_allclose(cs.guide_reward(Q, 1, 2, list(C0)), (0.02 * 1, 0.05 * -3), atol=1e-15)


@pytest.mark.parametrize("c0", [(0.01, 0.01), (0.01, -0.01, 0.05), (0.0, 0.01, 0.05), (0.01, float("nan"), 0.05),
                                ("a", "b", "c")])
def test_bad_c0(c0):
    with pytest.raises(InputError, match="c0"):
        two_segments().guide_reward(Q, 0, 0, c0)


@pytest.mark.parametrize("sl, sr, field", [(3, 0, "subtask_left"), (0, -1, "subtask_right"),
                                           ("screw", 0, "subtask_left"), (0, np.array([0, 5]), "subtask_right"),
                                           (0.5, 0, "subtask_left")])
def test_bad_subtask_argument(sl, sr, field):
    with pytest.raises(InputError, match=field):
        two_segments().guide_reward(Q, sl, sr)
    with pytest.raises(InputError, match=field):
        two_segments().inside(Q, sl, sr)


def test_bad_q_shape():
    with pytest.raises(InputError, match=r"q: expected shape \(\.\.\., 14\)"):
        two_segments().guide_reward(np.zeros(7), 0, 0)
    with pytest.raises(InputError, match=r"q: expected shape"):
        two_segments().inside(np.zeros((3, 13)), 0, 0)


# --------------------------------------------------------------------------- construction

def test_arrays_are_readonly_copies():
    lo, hi = C2_LO.copy(), C2_HI.copy()
    cs = ConstraintSet.single(lo, hi)
    lo[0] = -99.0
    assert cs.segments[0].lower[0] == -0.5
    assert cs.segments[0].lower.dtype == np.float64
    for arr in (cs.segments[0].lower, cs.segments[0].upper, cs.lower_by_subtask, cs.upper_by_subtask,
                cs.segment_of_subtask):
        with pytest.raises(ValueError):
            arr[0] = 1


def test_single_and_full_range():
    cs = ConstraintSet.single(C2_LO, C2_HI)
    assert cs.name == "C1"
    assert len(cs.segments) == 1 and cs.segments[0].subtasks == SUBTASKS
    assert cs.segment_of_subtask.tolist() == [0, 0, 0]
    full = ConstraintSet.full_range()
    np.testing.assert_array_equal(full.lower_by_subtask[2], LIM_LO)
    np.testing.assert_array_equal(full.upper_by_subtask[0], LIM_HI)
    np.testing.assert_allclose(full.guide_reward(np.zeros(14), 0, 2), [0.07, 0.35], atol=1e-15)


def test_segments_accepts_triples_and_list():
    a = ConstraintSet([("reach+grasp", C2_LO, C2_HI), (["align"], C3_LO, C3_HI)], name="C2C3")
    assert a == two_segments()
    assert isinstance(a.segments, tuple) and isinstance(a.segments[0], ConstraintSegment)


def test_equality_and_hash_ignore_provenance():
    a = two_segments(provenance={"x": 1})
    b = two_segments(provenance={"x": 2})
    assert a == b and hash(a) == hash(b)
    c = ConstraintSet.from_groups({"reach+grasp": (C2_LO, C2_HI), "align": (C3_LO, C3_HI + 1e-12)}, name="C2C3")
    assert a != c
    assert a != ConstraintSet.single(C2_LO, C2_HI, name="C2C3")


def _seg(subtasks, lo=C2_LO, hi=C2_HI):
    return (subtasks, lo, hi)


def _with(base, index, value):
    out = np.array(base, dtype=object)
    out[index] = value
    return list(out)


@pytest.mark.parametrize("segments, field", [
    ([], r"^segments: empty"),
    ([_seg(("reach", "screw")), _seg("align")], r"segments\[0\]\.subtasks\[1\]: unknown sub-task 'screw'"),
    ([_seg(()), _seg(SUBTASKS)], r"segments\[0\]\.subtasks: empty"),
    ([_seg("reach+grasp")], r"sub-task 'align' is not covered"),
    ([_seg("reach"), _seg("align")], r"sub-task 'grasp' is not covered"),
    ([_seg("reach+grasp"), _seg("grasp+align")], r"sub-task 'grasp' is covered by segments\[0\] and segments\[1\]"),
    ([_seg("reach+reach+grasp+align")], r"sub-task 'reach' is covered by segments\[0\] twice"),
    ([_seg("align"), _seg("reach+grasp")], r"segments\[0\] covers align: segments must follow"),
    ([_seg("reach+align"), _seg("grasp")], r"segments\[0\] covers reach\+align.*contiguous"),
    ([_seg("reach"), _seg("align+grasp")], r"segments\[1\] covers align\+grasp"),
    ([_seg("reach+grasp"), _seg("align", C3_LO[:13], C3_HI)],
     r"segments\[1\]\.lower: expected 14 values \(left_s0\.\.right_w2\), got 13"),
    ([_seg("reach+grasp"), _seg("align", np.zeros((2, 14)), C3_HI)], r"segments\[1\]\.lower: .*shape \(2, 14\)"),
    ([_seg("reach+grasp"), _seg("align", _with(C3_LO, 3, np.nan), C3_HI)],
     r"segments\[1\]\.lower\[3\] \(left_e1\): expected a finite number"),
    ([_seg("reach+grasp"), _seg("align", C3_LO, _with(C3_HI, 12, np.inf))],
     r"segments\[1\]\.upper\[12\] \(right_w1\): expected a finite number"),
    ([_seg(SUBTASKS, C2_LO, _with(C2_HI, 9, "x"))], r"segments\[0\]\.upper\[9\] \(right_e0\): expected a number"),
    ([_seg(SUBTASKS, _with(C2_LO, 0, True), C2_HI)], r"segments\[0\]\.lower\[0\] \(left_s0\): expected a number"),
    ([_seg(SUBTASKS, _with(C2_LO, 10, 0.3), C2_HI)],
     r"segments\[0\]\.lower\[10\] \(right_e1\) = 0\.3 is above segments\[0\]\.upper\[10\] = 0\.2"),
    ([_seg(SUBTASKS, "abc", C2_HI)], r"segments\[0\]\.lower: expected a list of 14 numbers"),
    (["reach"], r"segments\[0\]: expected a ConstraintSegment"),
])
def test_validation_errors_name_the_field(segments, field):
    with pytest.raises(InputError, match=field):
        ConstraintSet(segments)


def test_validation_errors_direct_segment_and_set_fields():
    with pytest.raises(InputError, match=r"^lower\[3\] \(left_e1\): expected a finite number"):
        ConstraintSegment(SUBTASKS, _with(C2_LO, 3, np.nan), C2_HI)
    with pytest.raises(InputError, match=r"^upper\[4\] \(left_w0\)|lower\[4\] \(left_w0\) = 0\.6 is above"):
        ConstraintSegment(SUBTASKS, _with(C2_LO, 4, 0.6), C2_HI)
    with pytest.raises(InputError, match=r"^name: expected a string"):
        ConstraintSet.single(C2_LO, C2_HI, name=3)
    with pytest.raises(InputError, match=r"^segments: expected a sequence"):
        ConstraintSet(ConstraintSegment(SUBTASKS, C2_LO, C2_HI))
    with pytest.raises(InputError, match=r"groups\['align'\]: expected a \(lower, upper\) pair"):
        ConstraintSet.from_groups({"reach+grasp": (C2_LO, C2_HI), "align": (C3_LO,)})


def test_validation_error_is_value_error_and_no_source():
    with pytest.raises(ValueError) as info:
        ConstraintSet([])
    assert isinstance(info.value, InputError) and info.value.source is None


# --------------------------------------------------------------------------- parse_segments

@pytest.mark.parametrize("spec, expected", [
    ("reach+grasp,align", (("reach", "grasp"), ("align",))),
    ("reach+grasp+align", (("reach", "grasp", "align"),)),
    ("reach,grasp,align", (("reach",), ("grasp",), ("align",))),
    ("reach, grasp + align", (("reach",), ("grasp", "align"))),
])
def test_parse_segments_good(spec, expected):
    assert parse_segments(spec) == expected


@pytest.mark.parametrize("spec, message", [
    ("", r"empty"),
    ("reach,,align", r"empty sub-task name in part 2"),
    ("reach+,grasp,align", r"empty sub-task name in part 1"),
    ("reach+grasp,screw", r"unknown sub-task 'screw'"),
    ("reach+grasp,grasp,align", r"sub-task 'grasp' is covered by parts\[0\] and parts\[1\]"),
    ("reach+grasp", r"sub-task 'align' is not covered"),
    ("reach+align,grasp", r"parts\[0\] covers reach\+align"),
    ("align,reach+grasp", r"parts\[0\] covers align"),
])
def test_parse_segments_bad(spec, message):
    with pytest.raises(InputError, match=message):
        parse_segments(spec)


def test_parse_segments_feeds_from_groups():
    groups = parse_segments("reach+grasp,align")
    cs = ConstraintSet.from_groups([(g, lo, hi) for g, (lo, hi) in zip(groups, [(C2_LO, C2_HI), (C3_LO, C3_HI)])],
                                   name="C2C3")
    assert cs == two_segments()


# --------------------------------------------------------------------------- volume fraction

def test_volume_fraction_hand_box():
    limits = np.tile([-1.0, 1.0], (7, 1))  # width 2 on every joint of both arms
    lo = np.zeros(14)
    hi = np.ones(14)
    hi[0] = 2.0      # clipped to 1: width 1 of 2
    lo[13] = -3.0    # clipped to -1: width 2 of 2
    cs = ConstraintSet.from_groups([("reach", lo, hi), ("grasp+align", np.full(14, 1.5), np.full(14, 2.0))])
    vf = cs.volume_fraction(limits)
    assert vf.shape == (2,)
    assert vf[0] == pytest.approx(0.5 ** 13, rel=1e-12)
    assert vf[1] == 0.0  # entirely outside the limits
    np.testing.assert_allclose(ConstraintSet.full_range().volume_fraction(), [1.0], rtol=1e-12)


def test_volume_fraction_baxter_half_width_on_one_joint():
    lo, hi = LIM_LO.copy(), LIM_HI.copy()
    hi[3] = (LIM_LO[3] + LIM_HI[3]) / 2  # left_e1 halved
    hi[10] = LIM_LO[10] + (LIM_HI[10] - LIM_LO[10]) / 4  # right_e1 quartered
    assert ConstraintSet.single(lo, hi).volume_fraction()[0] == pytest.approx(0.125, rel=1e-12)


# --------------------------------------------------------------------------- YAML

def awkward_set() -> ConstraintSet:
    lo, hi = bounds(7)
    lo[0], hi[0] = -1 / 3, 0.1
    lo[1], hi[1] = -0.0, 1e-17
    lo[5], hi[5] = LIM_LO[5], LIM_HI[5]  # exactly at the limits: no clipping
    lo2, hi2 = bounds(8)
    prov = {"demos": ["d1.csv", "d2.csv"], "params": {"margin_deg": 2.5, "count": 3, "ok": True},
            "note": "made by test", "nested": [{"a": 1}, None]}
    return ConstraintSet.from_groups([("reach+grasp", lo, hi), ("align", lo2, hi2)], name="C2C3", provenance=prov)


def test_yaml_round_trip_exact(tmp_path):
    cs = awkward_set()
    path = tmp_path / "c.yaml"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no clipping warning for in-limit bounds
        cs.save(path)
        back = ConstraintSet.load(path)
    assert back == cs
    for a, b in zip(back.segments, cs.segments):
        assert a.subtasks == b.subtasks
        assert np.array_equal(a.lower, b.lower) and np.array_equal(a.upper, b.upper)
        assert a.lower.tobytes() == b.lower.tobytes()  # bit-exact, -0.0 included
    assert back.provenance == cs.provenance
    assert back.name == "C2C3"
    assert os.listdir(tmp_path) == ["c.yaml"]  # no temp file left behind
    d = yaml.safe_load(path.read_text())
    assert d["schema_version"] == 1 and d["units"] == "rad"
    assert d["joints"] == list(JOINT_COLUMNS)
    assert d["segments"][0]["subtasks"] == ["reach", "grasp"]


def test_dict_round_trip():
    cs = awkward_set()
    d = cs.to_dict()
    assert set(d) == {"schema_version", "name", "units", "joints", "segments", "provenance"}
    back = ConstraintSet.from_dict(d)
    assert back == cs and back.provenance == cs.provenance


def test_save_overwrites_atomically(tmp_path, monkeypatch):
    path = tmp_path / "c.yaml"
    two_segments().save(path)
    before = path.read_bytes()
    # A failing dump (unrepresentable provenance) leaves the old file in place.
    with pytest.raises(yaml.YAMLError):
        two_segments(provenance={"bad": object()}).save(path)
    assert path.read_bytes() == before
    # A failing replace leaves the old file and removes the temporary file.

    def boom(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(C.os, "replace", boom)
    with pytest.raises(OSError, match="disk full"):
        awkward_set().save(path)
    assert path.read_bytes() == before
    assert os.listdir(tmp_path) == ["c.yaml"]
    monkeypatch.undo()
    awkward_set().save(path)
    assert ConstraintSet.load(path) == awkward_set()


def _good_dict() -> dict:
    """A valid file's mapping, every bound inside Baxter's limits."""
    return awkward_set().to_dict()


def _write(tmp_path, content) -> str:
    path = tmp_path / "bad.yaml"
    path.write_text(content if isinstance(content, str) else yaml.safe_dump(content, sort_keys=False))
    return str(path)


def _mutated(fn) -> dict:
    d = _good_dict()
    fn(d)
    return d


BAD_FILES = [
    ("missing segments", _mutated(lambda d: d.pop("segments")), r"segments: missing field"),
    ("missing schema_version", _mutated(lambda d: d.pop("schema_version")), r"schema_version: missing field"),
    ("missing joints", _mutated(lambda d: d.pop("joints")), r"joints: missing field"),
    ("missing upper", _mutated(lambda d: d["segments"][1].pop("upper")), r"segments\[1\]\.upper: missing field"),
    ("unknown top field", _mutated(lambda d: d.update(segmnts=[])), r"segmnts: unknown field"),
    ("unknown segment field", _mutated(lambda d: d["segments"][0].update(lowr=[])),
     r"segments\[0\]\.lowr: unknown field"),
    ("schema 2", _mutated(lambda d: d.update(schema_version=2)), r"schema_version: unsupported version 2"),
    ("schema str", _mutated(lambda d: d.update(schema_version="1")), r"schema_version: expected an integer"),
    ("units deg", _mutated(lambda d: d.update(units="deg")), r"units: expected 'rad'"),
    ("name list", _mutated(lambda d: d.update(name=["x"])), r"name: expected a string"),
    ("joints swapped", _mutated(lambda d: d["joints"].reverse()),
     r"joints: expected .*joints\[0\] = 'right_w2' where 'left_s0' is expected"),
    ("joints short", _mutated(lambda d: d["joints"].pop()), r"joints: expected .*got 13 names"),
    ("joints str", _mutated(lambda d: d.update(joints="left_s0")), r"joints: expected a list"),
    ("segments str", _mutated(lambda d: d.update(segments="reach")), r"segments: expected a list"),
    ("segments empty", _mutated(lambda d: d.update(segments=[])), r"segments: empty"),
    ("segment not mapping", _mutated(lambda d: d["segments"].__setitem__(0, [1, 2])),
     r"segments\[0\]: expected a mapping"),
    ("upper scalar", _mutated(lambda d: d["segments"][0].update(upper=0.5)),
     r"segments\[0\]\.upper: expected a list of 14 numbers"),
    ("lower short", _mutated(lambda d: d["segments"][1]["lower"].pop()),
     r"segments\[1\]\.lower: expected 14 values"),
    ("non-numeric", _mutated(lambda d: d["segments"][0]["upper"].__setitem__(3, "big")),
     r"segments\[0\]\.upper\[3\] \(left_e1\): expected a number, got str 'big'"),
    ("nan", _mutated(lambda d: d["segments"][1]["lower"].__setitem__(8, float("nan"))),
     r"segments\[1\]\.lower\[8\] \(right_s1\): expected a finite number"),
    ("lower above upper",
     _mutated(lambda d: d["segments"][0]["lower"].__setitem__(1, d["segments"][0]["upper"][1] + 0.5)),
     r"segments\[0\]\.lower\[1\] \(left_s1\) = \S+ is above segments\[0\]\.upper\[1\] = "),
    ("unknown subtask", _mutated(lambda d: d["segments"][1].update(subtasks=["screw"])),
     r"segments\[1\]\.subtasks\[0\]: unknown sub-task 'screw'"),
    ("subtasks int", _mutated(lambda d: d["segments"][1].update(subtasks=3)),
     r"segments\[1\]\.subtasks: expected a list"),
    ("align missing", _mutated(lambda d: d["segments"].pop()), r"sub-task 'align' is not covered"),
    ("provenance list", _mutated(lambda d: d.update(provenance=[1])), r"provenance: expected a mapping"),
    ("top-level list", [1, 2], r"expected a mapping with keys"),
    ("empty file", "", r"got an empty document"),
    ("yaml syntax", "schema_version: 1\nsegments: [\n  - {a: 1\n", r"YAML syntax error at line \d+, column \d+"),
    ("yaml tab", "name: x\n\tunits: rad\n", r"YAML syntax error"),
    ("exponent without dot", _mutated(lambda d: d["segments"][0]["lower"].__setitem__(2, "1e-3")),
     r"segments\[0\]\.lower\[2\] \(left_e0\): expected a number.*1\.0e-3"),
]


@pytest.mark.parametrize("kind, content, message", BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_load_errors_name_file_and_field(tmp_path, kind, content, message):
    path = _write(tmp_path, content)
    with pytest.raises(InputError, match=message) as info:
        ConstraintSet.load(path)
    assert info.value.source == path
    assert str(info.value).startswith(path + ": ")


def test_load_missing_file(tmp_path):
    path = str(tmp_path / "nope.yaml")
    with pytest.raises(InputError, match="cannot read constraint file") as info:
        ConstraintSet.load(path)
    assert info.value.source == path


def test_load_accepts_hand_written_ints_and_plus_string(tmp_path):
    text = ("schema_version: 1\nunits: rad\njoints: [" + ", ".join(JOINT_COLUMNS) + "]\nsegments:\n"
            "  - subtasks: reach+grasp+align\n"
            "    lower: [" + ", ".join(["-1"] * 14) + "]\n"
            "    upper: [" + ", ".join(["1"] * 14) + "]\n")
    path = _write(tmp_path, text)
    with pytest.warns(UserWarning, match=r"lower\[3\] \(left_e1\) -1\.0 -> -0\.05"):
        cs = ConstraintSet.load(path)
    assert cs.name == "" and cs.provenance == {}
    assert cs.segments[0].subtasks == SUBTASKS
    assert cs.segments[0].upper[1] == 1.0 and cs.segments[0].lower[0] == -1.0
    assert cs.segments[0].lower[3] == -0.05


# --------------------------------------------------------------------------- clipping

def test_clipping_warns_in_from_dict_and_load(tmp_path):
    d = _good_dict()
    d["segments"][0]["upper"][3] = 3.0      # left_e1 above 2.618
    d["segments"][1]["lower"][7] = -2.0     # right_s0 below -1.70168
    with pytest.warns(UserWarning) as record:
        cs = ConstraintSet.from_dict(d)
    messages = [str(w.message) for w in record]
    assert any(re.search(r"segments\[0\].*upper\[3\] \(left_e1\) 3\.0 -> 2\.618", m) for m in messages)
    assert any(re.search(r"segments\[1\].*lower\[7\] \(right_s0\) -2\.0 -> -1\.70168", m) for m in messages)
    assert cs.segments[0].upper[3] == 2.618
    assert cs.segments[1].lower[7] == -1.70168
    # in-limit values untouched
    np.testing.assert_array_equal(np.delete(cs.segments[0].upper, 3), np.delete(awkward_set().segments[0].upper, 3))
    np.testing.assert_array_equal(cs.segments[1].upper, awkward_set().segments[1].upper)

    path = _write(tmp_path, d)
    with pytest.warns(UserWarning) as record:
        loaded = ConstraintSet.load(path)
    messages = [str(w.message) for w in record]
    assert any(re.search(re.escape(path) + r": segments\[0\].*upper\[3\] \(left_e1\)", m) for m in messages)
    assert any(re.search(re.escape(path) + r": segments\[1\].*lower\[7\] \(right_s0\)", m) for m in messages)
    assert loaded == cs


def test_direct_construction_does_not_clip():
    hi = C2_HI.copy()
    hi[3] = 3.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cs = ConstraintSet.single(C2_LO, hi)
    assert cs.segments[0].upper[3] == 3.0
    # ...but a trip through a dict clips it, with a warning.
    with pytest.warns(UserWarning, match=r"upper\[3\] \(left_e1\)"):
        assert ConstraintSet.from_dict(cs.to_dict()).segments[0].upper[3] == 2.618


def test_sets_match_within_an_ulp_of_re_extraction_but_not_a_real_change(tmp_path):
    from dualarm.constraints.constraint_set import same_constraints

    base = ConstraintSet.single(C2_LO, C2_HI, name="a")
    ulp = ConstraintSet.single(np.nextafter(C2_LO, 1.0), C2_HI, name="a")
    moved = C2_HI.copy()
    moved[13] -= 1e-6
    assert base.matches(ulp) and ulp.matches(base)
    assert not base.matches(ConstraintSet.single(C2_LO, moved, name="a"))
    assert not base.matches(ConstraintSet.single(C2_LO, C2_HI, name="b"))
    base.save(tmp_path / "a.yaml")
    ulp.save(tmp_path / "b.yaml")
    assert (tmp_path / "a.yaml").read_bytes() != (tmp_path / "b.yaml").read_bytes()
    assert same_constraints(tmp_path / "a.yaml", tmp_path / "b.yaml")
    assert not same_constraints(tmp_path / "a.yaml", tmp_path / "missing.yaml")
