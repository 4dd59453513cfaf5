"""Standard D-H kinematic chains of the human arm (paper Table 1) and the Baxter arm (Table 2).

Frames and conventions
----------------------
Global frame G: the person stands facing +x, z points up, y to the person's left.
Standard Denavit-Hartenberg: link i is ``Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)`` with
``theta_i = q_i + offset_i``. Frame 0 is the arm's *base* frame; frame k moves with
joints 1..k. Joints q1..q7 are Baxter s0, s1, e0, e1, w0, w1, w2.

Both tables give, in their own base frame at q = 0, a straight arm along base +x
whose joint axes are, in order, base z, y, x, y, x, y, x (yaw, pitch, roll, pitch,
roll, pitch, roll). Each joint turns about the same base axis with the same sense
in both models, so **the same joint vector gives every link the same orientation
relative to the arm's base** (tested in ``tests/test_kinematics.py``). Where the
two differ, and why:

* Base frames. Baxter's base is its arm mount (z up, x forward and 45 degrees
  outward), so at q = 0 its arm points forward, horizontally. The human zero pose
  is standing with both arms hanging down, so the human base is
  ``HUMAN_BASE_ROTATION``: base x points down (-z_G), base y along -y_G, base z
  backward (-x_G). This is the one choice that keeps the human's elbow flexion
  positive, inside Baxter's one-sided elbow range e1 in [-0.05, 2.618]; it costs
  shoulder flexion above 60 degrees, which Baxter's s1 <= 1.047 cannot follow.
  In the world the two postures differ by the constant rotation between the bases.
* Link offsets. Baxter's a_1 = a_3 = 69 mm and a_5 = 10 mm move the joint
  centres off the roll axes, so the elbow-to-shoulder-pitch vector leans
  atan(0.069/0.364) = 10.7 degrees and the wrist-to-elbow vector 1.5 degrees off
  the human's; the roll axes (upper arm, forearm, hand directions) agree exactly.

Both arms of both models use the same D-H table with the same joint senses (as
Baxter does), so mirror-symmetric motions of the two arms have q1, q3, q5, q7 of
opposite signs and q2, q4, q6 equal.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from dualarm.task import ARMS, BAXTER_JOINT_NAMES  # noqa: F401  (re-exported)

JOINT_NAMES = ("q1", "q2", "q3", "q4", "q5", "q6", "q7")

#: Human base frame in G for both arms (columns: base x, y, z) = -z_G, -y_G, -x_G.
HUMAN_BASE_ROTATION = np.array([[0.0, 0.0, -1.0],
                                [0.0, -1.0, 0.0],
                                [-1.0, 0.0, 0.0]])

#: Baxter joint limits (rad), rows s0, s1, e0, e1, w0, w1, w2: [lower, upper].
BAXTER_JOINT_LIMITS = np.array([
    [-1.70168, 1.70168],
    [-2.147, 1.047],
    [-3.05418, 3.05418],
    [-0.05, 2.618],
    [-3.059, 3.059],
    [-1.5708, 2.094],
    [-3.059, 3.059],
])

#: Default adult segment lengths (m): shoulder-elbow, elbow-wrist, wrist-palm centre
#: (about 0.186, 0.146 and 0.045 of a 1.75 m stature; Winter, Biomechanics, 2009).
DEFAULT_HUMAN_LENGTHS = (0.32, 0.26, 0.08)


@dataclass(frozen=True)
class DHRow:
    """One standard D-H row: d (m), a (m), alpha (rad), offset added to q (rad)."""

    d: float
    a: float
    alpha: float
    offset: float


def human_dh_table(l1: float, l2: float, l3: float) -> tuple[DHRow, ...]:
    """Table 1 of the paper (human arm) with segment lengths l1, l2, l3 in metres."""
    h = np.pi / 2
    return (DHRow(0, 0, h, np.pi), DHRow(0, 0, h, -h), DHRow(l1, 0, h, np.pi),
            DHRow(0, 0, h, np.pi), DHRow(l2, 0, h, np.pi), DHRow(0, 0, h, np.pi),
            DHRow(l3, 0, 0, 0))


#: Table 2 of the paper (Baxter arm, either side).
BAXTER_DH_TABLE: tuple[DHRow, ...] = (
    DHRow(0.27, 0.069, -np.pi / 2, 0), DHRow(0, 0, np.pi / 2, np.pi / 2),
    DHRow(0.364, 0.069, -np.pi / 2, 0), DHRow(0, 0, np.pi / 2, 0),
    DHRow(0.375, 0.01, -np.pi / 2, 0), DHRow(0, 0, np.pi / 2, 0),
    DHRow(0.28, 0, 0, 0),
)


def packed(x) -> np.ndarray:
    """``x`` as a C-contiguous float64 array of the same shape (a copy only if it is strided).

    Feed numpy's sin, cos, arctan2 and the like through this when ``x`` may be a strided view
    (a column, a matrix entry over time). On AVX-512 CPUs numpy 1.26 computes them with a SIMD
    routine or with the C library's, two results that differ in the last bit, and for a
    strided input it picks by whether the output array happens to be allocated within
    ``stride x length`` bytes of the input's start: where earlier allocations left the heap
    decided. The same recording then mapped to joint angles a bit apart from run to run,
    and training runs with demonstrations did not repeat. Contiguous inputs always take the
    same routine.
    """
    return np.asarray(x, dtype=float, order="C")


def wrap_angle(angle):
    """Angles (rad, scalar or array) brought into [-pi, pi): the same rotation about one axis."""
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


def _homogeneous(rotation: np.ndarray, translation) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rotation
    T[:3, 3] = translation
    return T


@dataclass(frozen=True)
class ArmModel:
    """A 7-joint arm: D-H table, base pose in the world, optional joint limits.

    Attributes:
        name: e.g. ``'human_right'`` or ``'baxter_left'``.
        dh: seven D-H rows.
        base: (4, 4) pose of D-H frame 0 in the world frame (m).
        limits: (7, 2) [lower, upper] joint limits in rad, or None.
    """

    name: str
    dh: tuple[DHRow, ...]
    base: np.ndarray
    limits: np.ndarray | None = None

    def forward(self, q: np.ndarray) -> np.ndarray:
        """Forward kinematics, vectorised over leading axes.

        Args:
            q: (..., 7) joint angles, rad.
        Returns:
            (..., 8, 4, 4) poses in the world of D-H frames 0 (base) to 7 (end), m.
        """
        q = np.asarray(q, dtype=float)
        if q.shape[-1] != 7:
            raise ValueError(f"{self.name}: joint vector must have 7 entries, got shape {q.shape}")
        lead = q.shape[:-1]
        frames = np.empty(lead + (8, 4, 4))
        current = np.broadcast_to(self.base, lead + (4, 4)).copy()
        frames[..., 0, :, :] = current
        for i, row in enumerate(self.dh):
            theta = q[..., i] + row.offset
            ct, st = np.cos(theta), np.sin(theta)
            ca, sa = np.cos(row.alpha), np.sin(row.alpha)
            link = np.zeros(lead + (4, 4))
            link[..., 0, 0], link[..., 0, 1], link[..., 0, 2], link[..., 0, 3] = ct, -st * ca, st * sa, row.a * ct
            link[..., 1, 0], link[..., 1, 1], link[..., 1, 2], link[..., 1, 3] = st, ct * ca, -ct * sa, row.a * st
            link[..., 2, 1], link[..., 2, 2], link[..., 2, 3] = sa, ca, row.d
            link[..., 3, 3] = 1.0
            current = current @ link
            frames[..., i + 1, :, :] = current
        return frames

    def joint_positions(self, q: np.ndarray) -> np.ndarray:
        """(..., 7) joint angles (rad) -> (..., 8, 3) origins of frames 0..7 in the world (m)."""
        return self.forward(q)[..., :3, 3]

    def clip(self, q: np.ndarray) -> np.ndarray:
        """Clip (..., 7) joint angles to the limits (no-op without limits)."""
        if self.limits is None:
            return np.asarray(q, dtype=float)
        return np.clip(q, self.limits[:, 0], self.limits[:, 1])


def _side_sign(side: str) -> float:
    if side not in ARMS:
        raise ValueError(f"arm must be one of {ARMS}, got {side!r}")
    return 1.0 if side == "left" else -1.0


def human_arm(side: str, lengths: tuple[float, float, float] = DEFAULT_HUMAN_LENGTHS,
              shoulder_width: float = 0.36, shoulder_height: float = 1.45) -> ArmModel:
    """The human arm of Table 1 for ``side`` ('left' or 'right').

    Args:
        lengths: (l1, l2, l3) shoulder-elbow, elbow-wrist, wrist-palm in m.
        shoulder_width: distance between the two shoulder centres, m.
        shoulder_height: height of the shoulder centres above the floor, m.
    """
    l1, l2, l3 = lengths
    if min(lengths) <= 0:
        raise ValueError(f"segment lengths must be positive, got {lengths}")
    origin = (0.0, _side_sign(side) * shoulder_width / 2, shoulder_height)
    return ArmModel(f"human_{side}", human_dh_table(l1, l2, l3),
                    _homogeneous(HUMAN_BASE_ROTATION, origin))


def baxter_arm(side: str) -> ArmModel:
    """The Baxter arm of Table 2 for ``side``, based at its arm mount on the torso.

    Mount poses follow Baxter's URDF: (0.0246, +-0.2196, 0.1186) m from the torso
    origin, yawed +-45 degrees; the torso origin is put 0.93 m above the floor.
    """
    s = _side_sign(side)
    mount = Rotation.from_euler("z", s * np.pi / 4).as_matrix()
    return ArmModel(f"baxter_{side}", BAXTER_DH_TABLE,
                    _homogeneous(mount, (0.024645, s * 0.219645, 0.93 + 0.118588)),
                    BAXTER_JOINT_LIMITS.copy())


#: Joint-axis index in the base frame at q = 0 (0=x, 1=y, 2=z), joints q1..q7.
JOINT_AXES = (2, 1, 0, 1, 0, 1, 0)


def axis_rotation(axis: int, angle: np.ndarray) -> np.ndarray:
    """(...,) angles (rad) -> (..., 3, 3) rotation matrices about base axis 0=x, 1=y, 2=z."""
    angle = packed(angle)           # callers pass columns of (..., 7) joint vectors
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros(angle.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R[..., axis, axis] = 1.0
    R[..., i, i], R[..., j, j] = c, c
    R[..., i, j], R[..., j, i] = -s, s
    return R


def segment_rotations_in_base(q: np.ndarray) -> np.ndarray:
    """Rotation of the upper arm, forearm and hand since the zero pose, in base coordinates.

    Product of exponentials of the joint axes of ``JOINT_AXES``:
    upper arm ``Rz(q1) Ry(q2) Rx(q3)``, forearm ``... Ry(q4) Rx(q5)``,
    hand ``... Ry(q6) Rx(q7)``. Equals ``R_0k(q) R_0k(0)^T`` of the D-H chains for
    k = 3, 5, 7 (tested), and is what joint-angle extraction inverts.

    Args:
        q: (..., 7) joint angles, rad.
    Returns:
        (..., 3, 3, 3): index -3 is the segment (upper arm, forearm, hand).
    """
    q = np.asarray(q, dtype=float)
    out = np.empty(q.shape[:-1] + (3, 3, 3))
    R = axis_rotation(JOINT_AXES[0], q[..., 0])
    for k in range(1, 7):
        R = R @ axis_rotation(JOINT_AXES[k], q[..., k])
        if k in (2, 4, 6):
            out[..., k // 2 - 1, :, :] = R
    return out


#: Typical active range of motion of the right arm in this convention (rad), q1..q7:
#: shoulder yaw (abduction > 0), flexion (> 0), humeral roll; elbow flexion (> 0),
#: forearm roll; wrist flexion, hand roll. The left arm's is the mirror image
#: (q1, q3, q5, q7 negated). Used for tests, synthetic data and plots.
HUMAN_JOINT_RANGES_RIGHT = np.array([
    [-0.8, 2.6], [-1.0, 3.1], [-1.5, 1.5], [0.0, 2.6], [-1.5, 1.5], [-1.2, 1.2], [-1.0, 1.0],
])
MIRROR_SIGNS = np.array([-1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0])


def human_joint_ranges(side: str) -> np.ndarray:
    """(7, 2) [lower, upper] typical human joint ranges of ``side`` in rad."""
    if _side_sign(side) < 0:
        return HUMAN_JOINT_RANGES_RIGHT.copy()
    mirrored = HUMAN_JOINT_RANGES_RIGHT * MIRROR_SIGNS[:, None]
    return np.sort(mirrored, axis=1)
