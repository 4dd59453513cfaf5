"""Time parameterisation of a dual-arm trajectory within Baxter's joint limits (toppra).

The waypoints (time, 14 joints, 2 grips) define a geometric path through joint space; the
path between waypoints is a monotone cubic (PCHIP: continuous velocity, no overshoot, so a
path between waypoints inside the position limits stays inside them, and a joint that
rests between two waypoints stays still). TOPP-RA (Pham & Pham 2018, the ``toppra``
library) then finds the fastest traversal of that path within per-joint velocity and
acceleration limits, starting and ending at rest. Both arms and both grips are one path, so
they share one time axis. By default the traversal is never faster than the waypoints'
own timing (the path parameter is the original time, and its rate is limited to 1), so a
trajectory that already respects the limits keeps its timing.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator

from dualarm.errors import DualarmError, InputError
from dualarm.export.trajectory import JointTrajectory

#: Baxter's joint velocity limits (rad/s) for s0, s1, e0, e1, w0, w1, w2 (Rethink's hardware
#: specification, as in Baxter's URDF).
BAXTER_MAX_VELOCITY = (1.5, 1.5, 1.5, 1.5, 4.0, 4.0, 4.0)
#: Joint acceleration limits (rad/s^2) we chose: Baxter publishes none. Shoulder and elbow
#: reach their velocity limit in 0.375 s, the wrist in 0.5 s; conservative for a
#: series-elastic arm carrying a small box.
BAXTER_MAX_ACCELERATION = (4.0, 4.0, 4.0, 4.0, 8.0, 8.0, 8.0)
#: Gripper closure rate (1/s: open to closed in 0.5 s) and its rate of change (1/s^2).
GRIP_MAX_VELOCITY = 2.0
GRIP_MAX_ACCELERATION = 20.0
#: Smallest velocity or acceleration scale: 1 % of Baxter's limits (below it the arm barely
#: moves, and a traversal's duration runs towards infinity).
MIN_SCALE = 0.01
#: Most samples one export writes (about 2.8 h at 100 Hz): the rate times the duration is
#: bounded before anything is allocated.
MAX_SAMPLES = 1_000_000


class RetimeError(DualarmError):
    """No traversal of the path satisfies the limits (toppra found none)."""


@dataclass(frozen=True)
class Limits:
    """Velocity and acceleration limits of the 14 joints (left arm first) and the 2 grips.

    Attributes:
        velocity: (14,) rad/s.
        acceleration: (14,) rad/s^2.
        grip_velocity: closure per second (closure runs 0 open .. 1 closed).
        grip_acceleration: closure per second squared.
    """

    velocity: np.ndarray
    acceleration: np.ndarray
    grip_velocity: float = GRIP_MAX_VELOCITY
    grip_acceleration: float = GRIP_MAX_ACCELERATION

    @classmethod
    def baxter(cls, velocity_scale: float = 1.0, acceleration_scale: float = 1.0) -> "Limits":
        """Baxter's limits, each scaled (MoveIt's velocity and acceleration scaling factors)."""
        for name, value in (("velocity scale", velocity_scale), ("acceleration scale", acceleration_scale)):
            if not MIN_SCALE <= value <= 1:
                raise InputError(f"the {name} must be in [{MIN_SCALE}, 1], got {value}")
        return cls(np.tile(BAXTER_MAX_VELOCITY, 2) * velocity_scale,
                   np.tile(BAXTER_MAX_ACCELERATION, 2) * acceleration_scale,
                   GRIP_MAX_VELOCITY * velocity_scale, GRIP_MAX_ACCELERATION * acceleration_scale)

    def of_path(self, never_faster: bool) -> tuple[np.ndarray, np.ndarray]:
        """(velocity, acceleration) limits (17,) of the path's coordinates: 14 joints, 2 grips
        and the original time (rate at most 1 when ``never_faster``)."""
        time_rate = 1.0 if never_faster else 1e9
        v = np.concatenate([self.velocity, [self.grip_velocity] * 2, [time_rate]])
        a = np.concatenate([self.acceleration, [self.grip_acceleration] * 2, [1e9]])
        return v, a


class _MonotonePath:
    """A toppra geometric path through waypoints (N, dof) at positions ss (N,), piecewise
    monotone cubic (PCHIP) in each coordinate."""

    def __init__(self, ss: np.ndarray, waypoints: np.ndarray):
        self._ss, self._points = ss, waypoints
        self._spline = PchipInterpolator(ss, waypoints, axis=0)
        self._derivatives = [self._spline, self._spline.derivative(1), self._spline.derivative(2)]

    def __call__(self, path_positions, order: int = 0) -> np.ndarray:
        return self._derivatives[order](path_positions)

    def eval(self, ss):
        return self(ss, 0)

    def evald(self, ss):
        return self(ss, 1)

    def evaldd(self, ss):
        return self(ss, 2)

    @property
    def dof(self) -> int:
        return self._points.shape[1]

    @property
    def path_interval(self) -> np.ndarray:
        return np.array([self._ss[0], self._ss[-1]])

    @property
    def waypoints(self):
        return self._ss, self._points


@dataclass(frozen=True)
class Retimed:
    """A time-parameterised trajectory.

    Attributes:
        source: the waypoints it passes through.
        waypoint_time: (T,) s at which it passes each waypoint (0 at the first).
        duration: s.
        limits: the limits it was made for.
    """

    source: JointTrajectory
    waypoint_time: np.ndarray
    duration: float
    limits: Limits
    _traj: object        # toppra's parameterised trajectory: t -> the 17 path coordinates

    def sample(self, rate_hz: float) -> "Samples":
        """Positions, velocities and accelerations every 1/rate_hz s from 0 to the end (the
        last sample is at the end exactly)."""
        if not rate_hz > 0:
            raise InputError(f"the rate must be positive, got {rate_hz}")
        count = self.duration * rate_hz
        if not count < MAX_SAMPLES:
            raise InputError(f"the rate {rate_hz:g} Hz over the trajectory's {self.duration:g} s "
                             f"asks for {count:.3g} samples; at most {MAX_SAMPLES:,}: lower the rate")
        n = int(np.floor(count + 1e-9)) + 1
        t = np.arange(n) / rate_hz
        if t[-1] < self.duration - 1e-9:
            t = np.append(t, self.duration)
        return self.at(t)

    def at(self, t: np.ndarray) -> "Samples":
        """The trajectory at times t (N,) s in [0, duration]."""
        t = np.clip(np.asarray(t, float), 0.0, self.duration)
        x = np.atleast_2d(self._traj(t))            # (N, 17) path coordinates
        xd = np.atleast_2d(self._traj(t, 1))
        xdd = np.atleast_2d(self._traj(t, 2))
        return Samples(t, x[:, :14], xd[:, :14], xdd[:, :14], np.clip(x[:, 14:16], 0.0, 1.0))

    def report(self, rate_hz: float = 1000.0) -> dict:
        """What a person checks before sending it to hardware, from samples at ``rate_hz``:
        duration (s), per joint the peak |velocity| and |acceleration| and their ratio to the
        limit, and the largest deviation (rad) from the waypoints at their times."""
        s = self.sample(rate_hz)
        at_waypoints = self.at(self.waypoint_time)
        deviation = float(np.abs(at_waypoints.joints - self.source.joints).max())
        peak_v, peak_a = np.abs(s.velocity).max(axis=0), np.abs(s.acceleration).max(axis=0)
        return {"duration_s": self.duration, "source_duration_s": self.source.duration,
                "peak_velocity": peak_v, "velocity_ratio": peak_v / self.limits.velocity,
                "peak_acceleration": peak_a, "acceleration_ratio": peak_a / self.limits.acceleration,
                "waypoint_deviation_rad": deviation}


@dataclass(frozen=True)
class Samples:
    """A retimed trajectory sampled at times ``time`` (N,) s: joints, velocity, acceleration
    (N, 14) in rad, rad/s, rad/s^2, and grip closure (N, 2)."""

    time: np.ndarray
    joints: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    grip: np.ndarray

    def as_trajectory(self) -> JointTrajectory:
        return JointTrajectory(self.time, self.joints, self.grip)


def retime(trajectory: JointTrajectory, limits: Limits | None = None, never_faster: bool = True,
           grid_per_segment: int = 8, tolerance: float = 1e-3) -> Retimed:
    """The fastest traversal of ``trajectory``'s waypoints within ``limits`` (Baxter's by
    default), at rest at both ends.

    Args:
        trajectory: checked waypoints; their times order them (and bound the speed when
            ``never_faster``).
        limits: joint and grip limits.
        never_faster: never traverse a segment faster than the waypoints' own timing.
        grid_per_segment: TOPP-RA grid points per waypoint segment (limits are enforced on
            the grid; finer is slower and tighter).
        tolerance: largest allowed excess over a limit (relative) between grid points; the
            limits given to TOPP-RA are tightened and the solve repeated until it holds.

    Raises:
        RetimeError: no traversal within the limits exists.
    """
    import toppra.algorithm as algorithm
    import toppra.constraint as constraint

    limits = limits or Limits.baxter()
    trajectory.check()
    time = trajectory.time - trajectory.time[0]
    points = np.hstack([trajectory.joints, trajectory.grip, time[:, None]])
    path = _MonotonePath(time, points)
    grid = np.unique(np.concatenate([np.linspace(a, b, grid_per_segment + 1)
                                     for a, b in zip(time[:-1], time[1:])]))
    v_max, a_max = limits.of_path(never_faster)
    # toppra logs its own warnings when no traversal exists; RetimeError says it in one line
    logging.getLogger("toppra").setLevel(logging.ERROR)
    shrink = 1.0
    for _ in range(5):
        v = shrink * v_max
        a = shrink * a_max
        instance = algorithm.TOPPRA(
            [constraint.JointVelocityConstraint(np.stack([-v, v], axis=1)),
             constraint.JointAccelerationConstraint(np.stack([-a, a], axis=1))],
            path, gridpoints=grid, parametrizer="ParametrizeConstAccel")
        traj = instance.compute_trajectory(0.0, 0.0)
        if traj is None:
            raise RetimeError(f"no traversal of the {len(time)} waypoints within the limits "
                              f"({instance.problem_data.return_code})")
        data = instance.problem_data
        sd = np.maximum(data.sd_vec, 0.0)
        grid_time = np.concatenate([[0.0], np.cumsum(2 * np.diff(data.gridpoints)
                                                     / np.maximum(sd[:-1] + sd[1:], 1e-12))])
        result = Retimed(trajectory, np.interp(time, data.gridpoints, grid_time),
                         float(traj.duration), limits, traj)
        check = result.sample(min(1000.0, (MAX_SAMPLES - 1) / max(result.duration, 1e-9)))
        excess = max(float((np.abs(check.velocity) / limits.velocity).max()),
                     float((np.abs(check.acceleration) / limits.acceleration).max()))
        if excess <= 1 + tolerance:
            return result
        shrink /= excess
    raise RetimeError(f"the limits are exceeded by {100 * (excess - 1):.1f} % between grid "
                      "points; raise grid_per_segment")
