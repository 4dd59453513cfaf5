"""A dual-arm joint trajectory: one time axis, 14 joint angles and 2 grips; read, checked, written.

Our CSV layout (``dualarm export --format csv``): ``time`` (s), the 14 joint angles
``left_s0 .. left_w2, right_s0 .. right_w2`` (rad), ``grip_left, grip_right`` (closure,
0 open .. 1 closed).
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dualarm.atomic import atomic_open
from dualarm.task import JOINT_COLUMNS
from dualarm.errors import InputError
from dualarm.kinematics import BAXTER_JOINT_LIMITS

GRIP_COLUMNS = ("grip_left", "grip_right")
CSV_COLUMNS = ("time", *JOINT_COLUMNS, *GRIP_COLUMNS)
#: Lower and upper position limits (14, 2) rad of the columns of ``JOINT_COLUMNS``.
POSITION_LIMITS = np.vstack([BAXTER_JOINT_LIMITS, BAXTER_JOINT_LIMITS])
#: Slack (rad) on the position limits when checking a trajectory (rounding in files).
LIMIT_SLACK = 1e-6


#: Longest trajectory exported, s: a robot task of minutes, with room to spare; longer spans
#: are a unit mistake (ms for s) and would ask the retimer for billions of samples.
MAX_DURATION_S = 3600.0

@dataclass(frozen=True)
class JointTrajectory:
    """Both arms' joints and grips on one time axis.

    Attributes:
        time: (T,) s, strictly increasing.
        joints: (T, 14) rad, in the order of ``JOINT_COLUMNS`` (left arm first).
        grip: (T, 2) closure of the left and right gripper, 0 open .. 1 closed.
    """

    time: np.ndarray
    joints: np.ndarray
    grip: np.ndarray

    def check(self, where: str = "trajectory") -> "JointTrajectory":
        """Raise ``InputError`` naming ``where``, the row and the column for anything a robot
        must not be sent: fewer than 2 points, non-increasing time, NaN or infinite values,
        a joint outside Baxter's limits, a grip outside [0, 1] or a span over
        ``MAX_DURATION_S``. Returns self."""
        t, q, g = self.time, self.joints, self.grip
        if t.ndim != 1 or q.shape != (len(t), 14) or g.shape != (len(t), 2):
            raise InputError(f"{where}: expected time (T,), joints (T, 14), grip (T, 2); got "
                             f"{t.shape}, {q.shape}, {g.shape}")
        if len(t) < 2:
            raise InputError(f"{where}: a trajectory needs at least 2 points, got {len(t)}")
        for name, values in (("time", t[:, None]), *((c, q[:, [k]]) for k, c in enumerate(JOINT_COLUMNS)),
                             *((c, g[:, [k]]) for k, c in enumerate(GRIP_COLUMNS))):
            bad = np.flatnonzero(~np.isfinite(values[:, 0]))
            if len(bad):
                raise InputError(f"{where}: row {bad[0] + 1}, column {name}: {values[bad[0], 0]} "
                                 "is not a finite number")
        if t[-1] - t[0] > MAX_DURATION_S:
            raise InputError(f"{where}: column time spans {t[-1] - t[0]:g} s; a trajectory to "
                             f"export spans at most {MAX_DURATION_S:g} s (an hour)")
        step = np.diff(t)
        if (step <= 0).any():
            k = int(np.flatnonzero(step <= 0)[0])
            raise InputError(f"{where}: row {k + 2}, column time: {t[k + 1]:g} s does not come "
                             f"after {t[k]:g} s (time must strictly increase)")
        low, high = POSITION_LIMITS[:, 0] - LIMIT_SLACK, POSITION_LIMITS[:, 1] + LIMIT_SLACK
        outside = (q < low) | (q > high)
        if outside.any():
            row, col = (int(i) for i in np.argwhere(outside)[0])
            raise InputError(f"{where}: row {row + 1}, column {JOINT_COLUMNS[col]}: {q[row, col]:.4f} "
                             f"rad is outside Baxter's limits [{POSITION_LIMITS[col, 0]:.4f}, "
                             f"{POSITION_LIMITS[col, 1]:.4f}]")
        outside = (g < 0) | (g > 1)
        if outside.any():
            row, col = (int(i) for i in np.argwhere(outside)[0])
            raise InputError(f"{where}: row {row + 1}, column {GRIP_COLUMNS[col]}: {g[row, col]:g} "
                             "is outside [0, 1] (0 open, 1 closed)")
        return self

    @property
    def duration(self) -> float:
        """Seconds from the first point to the last."""
        return float(self.time[-1] - self.time[0])


def read_trajectory_csv(path: str | Path) -> JointTrajectory:
    """Read and check a trajectory in our CSV layout (``CSV_COLUMNS``; other columns are
    ignored). Errors name the file, the row and the column."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None
    reader = csv.reader(io.StringIO(text))
    header = next(reader, None)
    if header is None:
        raise InputError(f"{path}: empty file; expected the columns {', '.join(CSV_COLUMNS)}")
    header = [h.strip() for h in header]
    missing = [c for c in CSV_COLUMNS if c not in header]
    if missing:
        raise InputError(f"{path}: missing column(s) {', '.join(missing)}; a trajectory has "
                         f"{', '.join(CSV_COLUMNS)}")
    index = [header.index(c) for c in CSV_COLUMNS]
    values = []
    for row_number, row in enumerate(reader, start=2):
        if not row or all(not cell.strip() for cell in row):
            continue
        if len(row) != len(header):
            raise InputError(f"{path}: line {row_number} has {len(row)} fields, the header {len(header)}")
        out = []
        for column, k in zip(CSV_COLUMNS, index):
            try:
                out.append(float(row[k]))
            except ValueError:
                raise InputError(f"{path}: line {row_number}, column {column}: {row[k]!r} is not "
                                 "a number") from None
        values.append(out)
    data = np.array(values, dtype=float).reshape(-1, len(CSV_COLUMNS))
    return JointTrajectory(data[:, 0], data[:, 1:15], data[:, 15:17]).check(str(path))


def trajectory_csv_text(trajectory: JointTrajectory) -> str:
    """Our CSV layout as text (time in s to 1 us, angles in rad to 1e-6, grips to 1e-4)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for t, q, g in zip(trajectory.time, trajectory.joints, trajectory.grip):
        writer.writerow([f"{t:.6f}", *(f"{x:.6f}" for x in q), *(f"{x:.4f}" for x in g)])
    return out.getvalue()


def write_trajectory_csv(path: str | Path, trajectory: JointTrajectory) -> None:
    """Write ``trajectory`` in our CSV layout atomically."""
    with atomic_open(path) as f:
        f.write(trajectory_csv_text(trajectory).encode())


def from_episode(episode, dt: float) -> JointTrajectory:
    """The trajectory of an episode (``dualarm.envs.rollout.Episode``): its joint angles after
    the reset and after each step, its grip actions as closure (the fingers are open at the
    reset), ``dt`` s per step. The simulator's soft joint limits let a joint pass its limit
    by a hair under load; such angles are clipped onto the limit."""
    if not math.isfinite(dt) or dt <= 0:
        raise ValueError(f"the step time must be positive, got {dt}")
    joints = np.clip(np.asarray(episode.joint_angles, float), POSITION_LIMITS[:, 0], POSITION_LIMITS[:, 1])
    grip = np.vstack([np.zeros((1, 2)), 0.5 * (np.clip(episode.actions[:, :, -1], -1, 1) + 1.0)])
    return JointTrajectory(np.arange(len(joints)) * dt, joints, grip)
