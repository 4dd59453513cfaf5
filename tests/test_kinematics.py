"""D-H chains of the human arm and Baxter: the same joint vector, the same posture."""

import numpy as np
import pytest

from dualarm.kinematics import (ARMS, BAXTER_JOINT_LIMITS, HUMAN_BASE_ROTATION, baxter_arm, human_arm,
                                human_joint_ranges, segment_rotations_in_base)


def _random_q(n, seed=0):
    return np.random.default_rng(seed).uniform(-np.pi, np.pi, (n, 7))


def _base_relative(model, q):
    """Rotation of D-H frames 1..7 in the model's base frame (T, 7, 3, 3)."""
    F = model.forward(q)
    B = model.base[:3, :3]
    return np.einsum("ij,tkjl->tkil", B.T, F[:, 1:, :3, :3])


@pytest.mark.parametrize("side", ARMS)
def test_same_joint_vector_same_link_orientations(side):
    q = _random_q(500)
    human, robot = _base_relative(human_arm(side), q), _base_relative(baxter_arm(side), q)
    zero_h = _base_relative(human_arm(side), np.zeros((1, 7)))[0]
    zero_r = _base_relative(baxter_arm(side), np.zeros((1, 7)))[0]
    # Each link turns by the same rotation since q = 0 in both models.
    moved_h = human @ np.swapaxes(zero_h, -1, -2)
    moved_r = robot @ np.swapaxes(zero_r, -1, -2)
    np.testing.assert_allclose(moved_h, moved_r, atol=1e-12)


@pytest.mark.parametrize("side", ARMS)
def test_link_directions_agree_up_to_baxter_offsets(side):
    q = _random_q(500, seed=1)
    h, r = human_arm(side), baxter_arm(side)
    ph, pr = h.joint_positions(q), r.joint_positions(q)
    Bh, Br = h.base[:3, :3], r.base[:3, :3]

    def direction(p, a, b, B):
        v = (p[:, b] - p[:, a]) @ B  # in base coordinates
        return v / np.linalg.norm(v, axis=1, keepdims=True)

    def angle(u, v):
        return np.degrees(np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), np.sum(u * v, axis=1)))

    # Upper arm (shoulder pitch -> elbow), forearm (elbow -> wrist), hand (wrist -> end).
    upper = angle(direction(ph, 0, 3, Bh), direction(pr, 1, 3, Br))
    fore = angle(direction(ph, 3, 5, Bh), direction(pr, 3, 5, Br))
    hand = angle(direction(ph, 5, 7, Bh), direction(pr, 5, 7, Br))
    np.testing.assert_allclose(upper, np.degrees(np.arctan2(0.069, 0.364)), atol=1e-9)
    np.testing.assert_allclose(fore, np.degrees(np.arctan2(0.01, 0.375)), atol=1e-9)
    np.testing.assert_allclose(hand, 0.0, atol=1e-9)


def test_product_of_exponentials_matches_dh():
    q = _random_q(200, seed=2)
    for model in (human_arm("right"), baxter_arm("left")):
        rel = _base_relative(model, q) @ np.swapaxes(_base_relative(model, np.zeros((1, 7)))[0], -1, -2)
        np.testing.assert_allclose(rel[:, [2, 4, 6]], segment_rotations_in_base(q), atol=1e-12)


def test_human_zero_pose_hangs_down():
    for side in ARMS:
        p = human_arm(side, lengths=(0.3, 0.25, 0.1)).joint_positions(np.zeros(7))
        np.testing.assert_allclose(p[-1] - p[0], [0, 0, -0.65], atol=1e-12)
    assert np.allclose(HUMAN_BASE_ROTATION @ [1, 0, 0], [0, 0, -1])


def test_elbow_flexion_is_positive_and_moves_forearm_forward():
    q = np.zeros(7)
    q[3] = np.pi / 2
    p = human_arm("right").joint_positions(q)
    forearm = p[5] - p[3]
    assert forearm[0] > 0.25 and abs(forearm[2]) < 1e-9  # pointing forward (+x), horizontal
    assert BAXTER_JOINT_LIMITS[3, 0] < 0 < np.pi / 2 < BAXTER_JOINT_LIMITS[3, 1]


def test_shoulder_flexion_raises_arm_forward():
    q = np.zeros(7)
    q[1] = np.pi / 2
    p = human_arm("left").joint_positions(q)
    assert (p[3] - p[0])[0] > 0.3


def test_mirror_symmetry_of_joint_signs():
    rng = np.random.default_rng(3)
    q_right = rng.uniform(-1, 1, (50, 7))
    q_left = q_right * np.array([-1, 1, -1, 1, -1, 1, -1])
    pr = human_arm("right").joint_positions(q_right)
    pl = human_arm("left").joint_positions(q_left)
    mirrored = pr * np.array([1, -1, 1])
    np.testing.assert_allclose(pl, mirrored, atol=1e-12)
    lo, hi = human_joint_ranges("left").T
    assert np.all(lo <= hi)


def test_forward_checks_shape_and_clip():
    with pytest.raises(ValueError, match="7 entries"):
        baxter_arm("left").forward(np.zeros(6))
    q = np.full(7, 10.0)
    assert np.all(baxter_arm("right").clip(q) == BAXTER_JOINT_LIMITS[:, 1])
    with pytest.raises(ValueError):
        human_arm("middle")
