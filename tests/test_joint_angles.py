"""Calibration and joint-angle extraction: round trips, invariance, locality, continuity."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.spatial.transform import Rotation

from dualarm.errors import InputError
from dualarm.kinematics import human_joint_ranges
from dualarm.mocap.heading import estimate_heading_offsets
from dualarm.mocap.joint_angles import calibrate, joint_angles
from dualarm.mocap.mapping import map_recording
from dualarm.mocap.recording import Recording
from dualarm.mocap.synthetic import (example_motion, random_mountings, segment_orientations,
                                     sensor_quaternions, synthetic_recording)

RATE = 100.0
CALIB_SAMPLES = 20


def _path_from_zero(q_target: np.ndarray, n_move: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """Hold the zero pose for CALIB_SAMPLES, then move linearly in joint space to q_target."""
    s = np.concatenate([np.zeros(CALIB_SAMPLES), np.linspace(0, 1, n_move)])
    return np.arange(len(s)) / RATE, s[:, None] * q_target[None, :]


def _recover(t, q, mountings, **kw):
    rec = synthetic_recording(t, q, mountings=mountings, **kw)
    return joint_angles(rec, calibrate(rec, (CALIB_SAMPLES - 1) / RATE))


def _orientation_error(q_a: np.ndarray, q_b: np.ndarray) -> float:
    """Largest angle (rad) between the segment orientations produced by two joint trajectories."""
    a, b = segment_orientations(q_a), segment_orientations(q_b)
    return max(float((a[s].inv() * b[s]).magnitude().max()) for s in a)


def _joint_vector(draw) -> np.ndarray:
    q = []
    for side in ("left", "right"):
        ranges = human_joint_ranges(side)
        arm = [draw(st.floats(lo, hi, allow_nan=False)) for lo, hi in ranges]
        if draw(st.booleans()):  # near the shoulder singularity, q2 = +-pi/2
            sign = draw(st.sampled_from([1.0, -1.0]))
            arm[1] = sign * (np.pi / 2 - 10.0 ** -draw(st.integers(2, 7)) * draw(st.sampled_from([1.0, -1.0])))
        q.extend(arm)
    return np.array(q)


@st.composite
def joint_vectors(draw):
    return _joint_vector(draw)


@settings(max_examples=60, deadline=None)
@given(q_target=joint_vectors(), seed=st.integers(0, 2**32 - 1))
def test_round_trip_recovers_angles(q_target, seed):
    t, q = _path_from_zero(q_target)
    got = _recover(t, q, random_mountings(np.random.default_rng(seed)))
    assert np.all(np.isfinite(got.q))
    # Angles are defined wherever the shoulder is not exactly singular.
    regular = np.all(np.abs(np.cos(q[:, [1, 8]])) > 1e-7, axis=1)
    assert np.max(np.abs(got.q - q)[regular]) < 1e-6
    assert _orientation_error(got.q, q) < 1e-6
    assert np.max(got.residual) < 1e-6


def test_round_trip_through_exact_singularity():
    q_target = np.zeros(14)
    q_target[[0, 1, 2, 7, 8, 9]] = [0.7, np.pi, -1.1, -0.9, np.pi, 2.0]  # q2 passes pi/2 exactly
    t, q = _path_from_zero(q_target, n_move=401)
    assert np.any(np.abs(q[:, 1] - np.pi / 2) < 1e-15)
    got = _recover(t, q, random_mountings(np.random.default_rng(5)))
    regular = np.abs(np.cos(q[:, 1])) > 1e-7
    assert np.max(np.abs(got.q - q)[regular]) < 1e-6
    assert _orientation_error(got.q, q) < 1e-9


def test_angles_continuous_through_large_rolls():
    t = np.arange(0, 12, 0.01)
    s = np.clip((t - 1) / 10, 0, 1)
    q = np.zeros((len(t), 14))
    q[:, 2] = 9.0 * s      # humeral roll beyond 2 pi
    q[:, 4] = -8.0 * s     # forearm roll beyond 2 pi
    q[:, 1] = 2.5 * s      # shoulder flexion through 90 degrees
    q[:, 8] = 2.5 * np.sin(np.pi * s)
    got = _recover(t, q, random_mountings(np.random.default_rng(1)))
    assert np.max(np.abs(np.diff(got.q, axis=0))) < 0.2
    np.testing.assert_allclose(got.q, q, atol=1e-6)


@settings(max_examples=25, deadline=None)
@given(q_target=joint_vectors(), seed_a=st.integers(0, 10**9), seed_b=st.integers(0, 10**9))
def test_invariant_to_sensor_mountings(q_target, seed_a, seed_b):
    t, q = _path_from_zero(q_target, n_move=100)
    a = _recover(t, q, random_mountings(np.random.default_rng(seed_a)))
    b = _recover(t, q, random_mountings(np.random.default_rng(seed_b)))
    np.testing.assert_allclose(a.q, b.q, atol=1e-7)  # near-singular poses amplify rounding


def _two_sample_recording(quats_zero, quats_now):
    quat = {s: np.stack([quats_zero[s][0], quats_now[s][0]]) for s in quats_zero}
    return Recording(np.array([0.0, 1.0]), quat)


def _angles_before_after_turning(q_target, seed, segments):
    """Joint angles at ``q_target``, then with ``segments`` of each arm turned together by one
    random rotation (about the joint above them); returns the two (14,) angle vectors."""
    rng = np.random.default_rng(seed)
    mountings = random_mountings(rng)
    zero = sensor_quaternions(np.zeros((1, 14)), mountings)
    before = sensor_quaternions(q_target[None], mountings)
    after = dict(before)
    for arm in ("left", "right"):
        W = Rotation.random(random_state=rng)
        for seg in segments:
            s = f"{arm}_{seg}"
            after[s] = (W * Rotation.from_quat(before[s], scalar_first=True)).as_quat(scalar_first=True)
    angles = []
    for quats in (before, after):
        rec = _two_sample_recording(zero, quats)
        angles.append(joint_angles(rec, calibrate(rec, 0.5)).q[1])
    return angles


@settings(max_examples=40, deadline=None)
@given(q_target=joint_vectors(), seed=st.integers(0, 10**9))
def test_locality_hand_only_changes_wrist(q_target, seed):
    qa, qb = _angles_before_after_turning(q_target, seed, ("hand",))
    for arm in (slice(0, 7), slice(7, 14)):
        np.testing.assert_allclose(qb[arm][:5], qa[arm][:5], atol=1e-7)


@settings(max_examples=40, deadline=None)
@given(q_target=joint_vectors(), seed=st.integers(0, 10**9))
def test_locality_rigid_forearm_and_hand_only_changes_elbow(q_target, seed):
    qa, qb = _angles_before_after_turning(q_target, seed, ("forearm", "hand"))
    for arm in (slice(0, 7), slice(7, 14)):
        np.testing.assert_allclose(qb[arm][[0, 1, 2, 5, 6]], qa[arm][[0, 1, 2, 5, 6]], atol=1e-7)
        assert np.max(np.abs(qb[arm][[3, 4]] - qa[arm][[3, 4]])) > 1e-6  # the elbow did move


def test_calibration_window_gives_zero():
    t, q = example_motion(rate_hz=100.0, calib_s=1.5)
    rec = synthetic_recording(t, q, mountings=random_mountings(np.random.default_rng(2)))
    got = joint_angles(rec, calibrate(rec, 1.0))
    assert np.max(np.abs(got.q[t <= 1.0])) < 1e-6


def test_calibration_averages_the_window():
    """A noisy window: the rotation mean is far closer to the true mounting than one sample."""
    t = np.arange(0, 3, 0.01)
    q = np.zeros((len(t), 14))
    truth = random_mountings(np.random.default_rng(4))
    rec = synthetic_recording(t, q, mountings=truth, noise_rad=np.deg2rad(2.0), rng=np.random.default_rng(5))
    with pytest.warns(UserWarning, match="inside the calibration window"):
        calib = calibrate(rec, 2.0)  # 2 degrees of noise per axis: the stillness check fires
    for s, true in truth.items():
        estimate = Rotation.from_quat(calib.mounting[s], scalar_first=True)
        assert np.degrees((true.inv() * estimate).magnitude()) < 0.5
        assert calib.spread[s] > np.deg2rad(5.0)


def test_calibration_window_too_long():
    t, q = example_motion(duration_s=3.0, calib_s=1.0)
    rec = synthetic_recording(t, q)
    with pytest.raises(InputError, match="longer than the recording"):
        calibrate(rec, 5.0)
    with pytest.raises(InputError, match="positive"):
        calibrate(rec, 0.0)


def test_residual_measures_unrepresentable_rotation():
    """A forearm turned about the axis no elbow DOF covers: residual = that angle."""
    t = np.array([0.0, 1.0])
    zero = segment_orientations(np.zeros((2, 14)))
    quat = {s: r.as_quat(scalar_first=True) for s, r in zero.items()}
    angle = 0.3
    # Rotation about the global forward axis (x_G) of the right forearm and hand at t = 1.
    turn = Rotation.from_euler("x", angle)
    for s in ("right_forearm", "right_hand"):
        quat[s][1] = (turn * zero[s][1]).as_quat(scalar_first=True)
    rec = Recording(t, quat)
    got = joint_angles(rec, calibrate(rec, 0.5))
    assert got.residual[1, 2] == pytest.approx(angle, abs=1e-12)   # right elbow
    assert got.residual[1, 3] == pytest.approx(0.0, abs=1e-12)     # right wrist
    assert np.all(got.residual[:, :2] < 1e-12)


def test_heading_offsets_detected_and_corrected():
    t, q = example_motion(rate_hz=100.0)
    offsets = {"left_forearm": 0.6, "right_hand": -0.4, "right_forearm": 1.2}
    rng = np.random.default_rng(7)
    rec = synthetic_recording(t, q, mountings=random_mountings(rng), heading_offsets=offsets)
    raw = map_recording(rec, heading="off")
    fixed = map_recording(rec, heading="auto")
    assert np.max(np.abs(raw.joints.q - q)) > 0.3
    np.testing.assert_allclose(fixed.joints.q, q, atol=1e-5)
    found = {e.sensor: e for e in fixed.heading}
    for s, d in offsets.items():
        assert found[s].detected and found[s].offset_rad == pytest.approx(d, abs=1e-6)
    assert not found["left_hand"].detected and found["left_hand"].offset_rad == 0.0


@pytest.mark.parametrize("facing_deg", [35.0, 90.0, 180.0, -120.0])
def test_arm_facing_recovered_from_elbow(facing_deg):
    """The person faces another heading in one arm's sensor frames (all three sensors turned alike),
    and the right forearm has its own offset on top."""
    t, q = example_motion(rate_hz=100.0)
    facing = np.deg2rad(facing_deg)
    offsets = {"left_upper_arm": facing, "left_forearm": facing, "left_hand": facing,
               "right_forearm": 0.5}
    rec = synthetic_recording(t, q, mountings=random_mountings(np.random.default_rng(11)),
                              heading_offsets=offsets)
    assert np.max(np.abs(map_recording(rec, heading="off").joints.q - q)) > 0.3
    fixed = map_recording(rec, heading="auto")
    np.testing.assert_allclose(fixed.joints.q, q, atol=1e-5)
    left_elbow = next(e for e in fixed.heading if e.sensor == "left_forearm")
    assert left_elbow.detected and abs(np.angle(np.exp(1j * (left_elbow.axis_rad - facing)))) < 1e-6


def test_heading_not_corrected_without_evidence():
    """Straight arms turning about the vertical only: a heading offset is not observable."""
    t = np.arange(0, 5, 0.01)
    q = np.zeros((len(t), 14))
    q[:, [2, 4, 6, 9, 11, 13]] = np.clip(t - 1, 0, None)[:, None] * 0.3  # roll joints only
    rec = synthetic_recording(t, q, heading_offsets={"left_forearm": 0.8})
    estimates = estimate_heading_offsets(rec, calibrate(rec, 1.0))
    assert not any(e.detected for e in estimates)


def test_palms_in_calibration_recovered_as_forearm_roll():
    """Calibrating with palms towards the thighs (forearm roll q5 = -+80 deg, not 0): the wrist
    axis fit finds the twist, and the angles come back in the model's convention."""
    t, q = example_motion(rate_hz=100.0)
    q = q.copy()
    q[:, 4] += np.deg2rad(80.0)    # left q5
    q[:, 11] -= np.deg2rad(80.0)   # right q5 (mirror image)
    rec = synthetic_recording(t, q, mountings=random_mountings(np.random.default_rng(12)),
                              heading_offsets={"right_hand": -0.3})
    assert np.max(np.abs(map_recording(rec, heading="off").joints.residual[:, [1, 3]])) > 0.1
    fixed = map_recording(rec, heading="auto")
    np.testing.assert_allclose(fixed.joints.q, q, atol=1e-5)
    assert np.max(fixed.joints.residual) < 1e-5


#: numpy ufuncs with a SIMD routine beside the C library's (numpy 1.26 on AVX-512 CPUs).
SIMD_UFUNCS = ("sin", "cos", "tan", "arcsin", "arccos", "arctan", "arctan2", "hypot", "exp",
               "log", "power", "tanh")


def test_mapping_hands_numpy_trigonometry_contiguous_arrays_only(monkeypatch):
    """Mapping a shipped recording (heading, calibration, joint angles, Baxter's kinematics)
    never gives numpy's sin, cos, arctan2... a strided array: for one, numpy chooses its SIMD
    or its C-library routine, whose results differ in the last bit, by where the output array
    happened to be allocated, and the same recording mapped a bit differently from run to run
    (``dualarm.kinematics.packed``)."""
    import sys

    from dualarm.demos.formats import DEFAULT_DEMO_DIR
    from dualarm.demos.loading import load_demo
    from dualarm.kinematics import baxter_arm, segment_rotations_in_base

    calls = []
    for name in SIMD_UFUNCS:
        def strict(*args, _ufunc=getattr(np, name), **kwargs):
            caller = sys._getframe(1).f_globals.get("__name__", "")
            if caller.startswith("dualarm"):
                strided = [a.strides for a in args if isinstance(a, np.ndarray) and not a.flags.c_contiguous]
                assert not strided, f"{caller} calls np.{_ufunc.__name__} on a strided array {strided}"
                calls.append(_ufunc.__name__)
            return _ufunc(*args, **kwargs)
        monkeypatch.setattr(np, name, strict)
    demo = load_demo(DEFAULT_DEMO_DIR / "demo_00.csv.gz")
    segment_rotations_in_base(demo.q[:, :7])
    baxter_arm("right").forward(demo.q[:, 7:])           # the replays' hand paths
    assert {"arctan2", "cos", "sin"} <= set(calls)
