"""Tests of dualarm.mocap.fusion: raw acc + gyr -> orientation, for every method."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dualarm.errors import InputError
from dualarm.mocap.fusion import METHODS, orientation_from_imu

RATE = 100.0
G = np.array([0.0, 0.0, 9.81])
EZ = np.array([0.0, 0.0, 1.0])


def _rot(q: np.ndarray) -> Rotation:
    return Rotation.from_quat(q, scalar_first=True)


def _inclination_error_deg(q: np.ndarray, truth: Rotation) -> np.ndarray:
    """Angle between the global vertical seen from the sensor, estimate vs truth."""
    up_est = _rot(q).inv().apply(EZ)
    up_true = truth.inv().apply(EZ)
    cos = np.clip(np.sum(np.atleast_2d(up_est) * np.atleast_2d(up_true), axis=1), -1.0, 1.0)
    return np.degrees(np.arccos(cos))


def _noise(shape, scale, seed):
    return np.random.default_rng(seed).normal(0.0, scale, shape)


@pytest.mark.parametrize("method", METHODS)
def test_stationary_level_sensor_has_vertical_z_axis(method):
    n = 500
    acc = np.tile(G, (n, 1)) + _noise((n, 3), 0.02, 1)
    gyr = _noise((n, 3), 0.002, 2)
    q = orientation_from_imu(acc, gyr, RATE, method=method)
    assert q.shape == (n, 4)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-9)
    z_axis_global = _rot(q).apply(EZ)  # the sensor's own z axis, in the global frame
    angle = np.degrees(np.arccos(np.clip(z_axis_global[-100:] @ EZ, -1, 1)))
    assert angle.max() < 1.0


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("rotvec_deg", [(30.0, 0.0, 0.0), (0.0, -50.0, 0.0), (25.0, 35.0, 10.0)])
def test_tilted_static_sensor_converges_to_its_inclination(method, rotvec_deg):
    # Asymmetric tilts: an estimate in the transposed (global -> sensor) convention
    # would show the opposite tilt and fail by twice the angle.
    truth = Rotation.from_rotvec(np.radians(rotvec_deg))
    n = 1000
    acc = np.tile(truth.inv().apply(G), (n, 1)) + _noise((n, 3), 0.02, 3)
    gyr = _noise((n, 3), 0.002, 4)
    q = orientation_from_imu(acc, gyr, RATE, method=method)
    assert _inclination_error_deg(q[-200:], truth).max() < 2.0


@pytest.mark.parametrize("method", METHODS)
def test_rotation_about_sensor_x_is_tracked(method):
    # Level, then 2 s at 30 deg/s about the sensor's own x axis, then 3 s at rest.
    w = np.radians(30.0)
    t = np.arange(int(5 * RATE)) / RATE
    angle = np.clip(t - 0.0, 0.0, 2.0) * w
    truth = Rotation.from_rotvec(np.outer(angle, [1.0, 0.0, 0.0]))
    acc = truth.inv().apply(G)
    gyr = np.zeros((len(t), 3))
    gyr[(t >= 0.0) & (t < 2.0), 0] = w
    q = orientation_from_imu(acc, gyr, RATE, method=method)
    err = _inclination_error_deg(q, truth)
    assert err[-1] < 2.0
    assert err.max() < 5.0


@pytest.mark.parametrize("method", METHODS)
def test_rotation_about_vertical_gives_heading_change(method):
    rate_dps = 12.0
    n = int(10 * RATE) + 1  # 10 s between the first and last sample
    acc = np.tile(G, (n, 1))
    gyr = np.tile([0.0, 0.0, np.radians(rate_dps)], (n, 1))
    q = orientation_from_imu(acc, gyr, RATE, method=method)
    # heading change in the global frame: R_end R_start^T, a rotation about z
    delta = (_rot(q[-1]) * _rot(q[0]).inv()).as_rotvec(degrees=True)
    assert abs(delta[2] - 10 * rate_dps) < 2.0
    assert np.hypot(delta[0], delta[1]) < 1.0


@pytest.mark.parametrize("field,shape_acc,shape_gyr", [
    ("acc", (10, 2), (10, 3)),
    ("acc", (10,), (10, 3)),
    ("acc", (0, 3), (0, 3)),
    ("gyr", (10, 3), (10, 4)),
    ("gyr", (10, 3), (9, 3)),
])
def test_bad_shapes_name_the_field(field, shape_acc, shape_gyr):
    with pytest.raises(InputError) as info:
        orientation_from_imu(np.zeros(shape_acc), np.zeros(shape_gyr), RATE)
    assert info.value.column == field
    assert f"'{field}'" in str(info.value)


@pytest.mark.parametrize("field", ["acc", "gyr"])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_value_names_field_and_first_row(field, bad):
    data = {"acc": np.tile(G, (20, 1)), "gyr": np.zeros((20, 3))}
    data[field][6, 1] = bad   # 1-based row 7
    data[field][12, 0] = bad  # a later bad row is not the one reported
    with pytest.raises(InputError) as info:
        orientation_from_imu(data["acc"], data["gyr"], RATE)
    assert info.value.column == field
    assert info.value.row == 7
    assert "row 7" in str(info.value) and f"'{field}'" in str(info.value)


def test_unknown_method_lists_the_choices():
    with pytest.raises(InputError) as info:
        orientation_from_imu(np.tile(G, (5, 1)), np.zeros((5, 3)), RATE, method="kalman")
    message = str(info.value)
    assert "kalman" in message
    for name in METHODS:
        assert name in message


@pytest.mark.parametrize("rate", [0.0, -100.0, np.nan])
def test_bad_rate_is_rejected(rate):
    with pytest.raises(InputError, match="rate_hz"):
        orientation_from_imu(np.tile(G, (5, 1)), np.zeros((5, 3)), rate)


def test_non_contiguous_and_integer_input_is_accepted():
    acc = np.asfortranarray(np.tile([0, 0, 10], (50, 1)))  # int, Fortran order
    gyr = np.zeros((3, 50)).T  # a transposed (non C-contiguous) view
    q = orientation_from_imu(acc, gyr, RATE)
    assert q.shape == (50, 4) and np.isfinite(q).all()
