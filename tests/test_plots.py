"""Tests of dualarm.mocap.plots: PNGs are written, readable, atomically, with the right shapes."""

from __future__ import annotations

import subprocess
import sys
from types import SimpleNamespace

import matplotlib.image
import numpy as np
import pytest

from dualarm.kinematics import BAXTER_JOINT_LIMITS, baxter_arm, human_arm
from dualarm.mocap.plots import (DPI, plot_joint_angles, plot_residuals, plot_stick_figures,
                                 stick_points)
from dualarm.mocap.retarget import to_baxter
from dualarm.mocap.synthetic import example_motion


@pytest.fixture(scope="module")
def motion():
    t, q = example_motion(duration_s=6.0, rate_hz=25.0, calib_s=0.5)
    residual = np.abs(np.sin(np.outer(t, [1.0, 2.0, 3.0, 4.0]))) * 0.05
    return t, q, residual


def _read(path) -> np.ndarray:
    assert path.is_file() and path.stat().st_size > 0
    img = matplotlib.image.imread(path)
    assert img.ndim == 3 and img.shape[2] in (3, 4)
    assert np.ptp(img[..., :3]) > 0.5  # not a blank canvas
    return img


def _no_temp_files(directory) -> None:
    assert sorted(p.name for p in directory.iterdir() if p.name.startswith(".")) == []


def test_joint_angles_png(tmp_path, motion):
    t, q, residual = motion
    plain = plot_joint_angles(t, q, tmp_path / "q.png", title="demo")
    full = plot_joint_angles(t, q, tmp_path / "q_full.png", limits=BAXTER_JOINT_LIMITS,
                             residual=residual)
    a, b = _read(plain), _read(full)
    # 7 (or 8) rows by 2 columns: portrait, same width, the residual row adds height.
    assert a.shape[0] > a.shape[1] and b.shape[0] > a.shape[0] and b.shape[1] == a.shape[1]
    assert a.shape[1] % DPI == 0
    _no_temp_files(tmp_path)


def test_save_creates_directory_and_overwrites(tmp_path, motion):
    t, _, residual = motion
    target = tmp_path / "sub" / "r.png"
    plot_residuals(t, residual, target)
    first = target.read_bytes()
    plot_residuals(t, 2 * residual, target)
    assert target.read_bytes() != first
    _read(target)
    _no_temp_files(target.parent)


def test_joint_angles_rejects_bad_shapes(tmp_path, motion):
    t, q, residual = motion
    with pytest.raises(ValueError):
        plot_joint_angles(t, q[:, :7], tmp_path / "x.png")
    with pytest.raises(ValueError):
        plot_joint_angles(t[:-1], q, tmp_path / "x.png")
    with pytest.raises(ValueError):
        plot_joint_angles(t, q, tmp_path / "x.png", limits=BAXTER_JOINT_LIMITS[:6])
    with pytest.raises(ValueError):
        plot_joint_angles(t, q, tmp_path / "x.png", residual=residual[:, :2])
    assert not (tmp_path / "x.png").exists()
    _no_temp_files(tmp_path)


def test_stick_figures_png(tmp_path, motion):
    t, q, _ = motion
    qr = to_baxter(q).q
    one = _read(plot_stick_figures(q, qr, [0], tmp_path / "s1.png", time=t))
    peak = int(np.argmax(q[:, 8]))
    three = _read(plot_stick_figures(q, qr, [0, peak // 2, peak], tmp_path / "s3.png",
                                     lengths=(0.30, 0.25, 0.07)))
    # One row of two panels is landscape; each instant adds a row of the same width.
    assert one.shape[1] > one.shape[0]
    assert three.shape[1] == one.shape[1] and three.shape[0] > 2.5 * one.shape[0]
    _no_temp_files(tmp_path)


def test_stick_figures_rejects_bad_input(tmp_path, motion):
    t, q, _ = motion
    with pytest.raises(ValueError):
        plot_stick_figures(q, q[:-1], [0], tmp_path / "s.png")
    with pytest.raises(ValueError):
        plot_stick_figures(q, q, [len(q)], tmp_path / "s.png")
    with pytest.raises(ValueError):
        plot_stick_figures(q, q, [], tmp_path / "s.png")


@pytest.mark.parametrize("side", ["left", "right"])
def test_human_zero_pose_hands_hang_below_shoulders(side):
    arm = human_arm(side)
    p = stick_points(arm, np.zeros(7))
    assert p.shape == (8, 3)
    shoulder, hand = p[0], p[7]
    np.testing.assert_allclose(shoulder, arm.base[:3, 3])
    assert hand[2] < shoulder[2] - 0.5  # l1 + l2 + l3 = 0.66 m straight down
    np.testing.assert_allclose(hand[:2], shoulder[:2], atol=1e-9)
    assert np.sign(shoulder[1]) == (1 if side == "left" else -1)


@pytest.mark.parametrize("side", ["left", "right"])
def test_baxter_zero_pose_reaches_forward(side):
    p = stick_points(baxter_arm(side), np.zeros(7))
    assert p.shape == (8, 3)
    mount, hand = p[0], p[7]
    assert hand[0] > mount[0] + 0.5                  # forward
    assert abs(hand[2] - p[1][2]) < 0.1              # horizontal after the shoulder riser
    assert np.sign(hand[1] - mount[1]) == (1 if side == "left" else -1)  # 45 deg outward


def test_stick_points_batch():
    q = np.zeros((5, 7))
    assert stick_points(human_arm("left"), q).shape == (5, 8, 3)


def test_residuals_png(tmp_path, motion):
    t, _, residual = motion
    estimates = [SimpleNamespace(sensor="right_forearm", offset_rad=0.3, rms_before_rad=0.18,
                                 rms_after_rad=0.01, detected=True),
                 SimpleNamespace(sensor="right_hand", offset_rad=0.0, rms_before_rad=0.01,
                                 rms_after_rad=0.01, detected=False)]
    bare = _read(plot_residuals(t, residual, tmp_path / "r.png"))
    boxed = _read(plot_residuals(t, residual, tmp_path / "rh.png", heading_estimates=estimates))
    assert bare.shape[1] > bare.shape[0]
    assert boxed.shape[1] == bare.shape[1] and boxed.shape[0] > bare.shape[0]
    with pytest.raises(ValueError):
        plot_residuals(t, residual[:, :3], tmp_path / "bad.png")
    _no_temp_files(tmp_path)


def test_module_does_not_use_pyplot():
    code = "import sys, dualarm.mocap.plots; sys.exit('matplotlib.pyplot' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0
