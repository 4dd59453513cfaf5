"""The `Recording` value (time + six sensor orientations) and its validation.

Conventions: quaternions are scalar first (w, x, y, z) and give the orientation
of the sensor frame in the (sensor's) global frame; time is in seconds.
Readers and writers for CSV, OpenSim ``.sto`` and MATLAB ``.mat`` live in
:mod:`dualarm.mocap.io`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from dualarm.errors import InputError
from dualarm.task import ARMS  # noqa: F401  (part of this module's vocabulary)

#: The six sensors, left arm first, proximal to distal.
SENSORS: tuple[str, ...] = (
    "left_upper_arm", "left_forearm", "left_hand",
    "right_upper_arm", "right_forearm", "right_hand",
)
SEGMENTS: tuple[str, ...] = ("upper_arm", "forearm", "hand")

#: Largest accepted deviation of a quaternion's norm from 1.
QUAT_NORM_TOLERANCE = 1e-3


def sensor_name(arm: str, segment: str) -> str:
    """The sensor name of ``segment`` on ``arm``, e.g. ``('left', 'hand') -> 'left_hand'``."""
    return f"{arm}_{segment}"


@dataclass(frozen=True)
class Recording:
    """An IMU recording of both arms.

    Attributes:
        time: (T,) seconds, strictly increasing.
        quat: sensor name -> (T, 4) unit quaternions, scalar first, orientation of
            the sensor frame in the global frame. Either sign is accepted.
        acc: optional sensor name -> (T, 3) accelerometer, m/s^2, sensor frame.
        gyr: optional sensor name -> (T, 3) gyroscope, rad/s, sensor frame.
        source: where the recording came from (a path), used in error messages.
    """

    time: np.ndarray
    quat: dict[str, np.ndarray]
    acc: dict[str, np.ndarray] = field(default_factory=dict)
    gyr: dict[str, np.ndarray] = field(default_factory=dict)
    source: str = "<recording>"

    def __post_init__(self) -> None:
        validate_recording(self)

    @property
    def n_samples(self) -> int:
        """Number of samples T."""
        return int(self.time.shape[0])

    @property
    def duration(self) -> float:
        """Seconds from the first to the last sample."""
        return float(self.time[-1] - self.time[0]) if self.n_samples else 0.0

    @property
    def rate_hz(self) -> float:
        """Mean sampling rate in Hz."""
        return (self.n_samples - 1) / self.duration if self.duration > 0 else float("nan")


def validate_recording(rec: Recording) -> None:
    """Check shapes, finiteness, time order and quaternion norms.

    Raises:
        InputError: naming ``rec.source``, the first bad row (1-based) and the column.
    """
    src = rec.source
    t = np.asarray(rec.time)
    if t.ndim != 1:
        raise InputError(f"time must be 1-D, got shape {t.shape}", source=src, column="time")
    if t.shape[0] == 0:
        raise InputError("recording has no samples", source=src)
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise InputError("time is not a finite number", source=src, row=int(bad[0]) + 1, column="time")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise InputError(f"time is not strictly increasing ({float(t[i - 1])!r} then {float(t[i])!r})",
                         source=src, row=i + 1, column="time")
    missing = [s for s in SENSORS if s not in rec.quat]
    if missing:
        raise InputError(f"missing orientation of sensor(s) {', '.join(missing)}", source=src)
    T = t.shape[0]
    for s in SENSORS:
        q = np.asarray(rec.quat[s])
        if q.shape != (T, 4):
            raise InputError(f"quaternions must have shape ({T}, 4), got {q.shape}", source=src, column=f"{s}_q")
        finite = np.isfinite(q).all(axis=1)
        bad = np.flatnonzero(~finite)
        if bad.size:
            col = "wxyz"[int(np.flatnonzero(~np.isfinite(q[bad[0]]))[0])]
            raise InputError("quaternion component is NaN or infinite", source=src,
                             row=int(bad[0]) + 1, column=f"{s}_q{col}")
        norm = np.linalg.norm(q, axis=1)
        bad = np.flatnonzero(np.abs(norm - 1.0) > QUAT_NORM_TOLERANCE)
        if bad.size:
            i = int(bad[0])
            what = "zero quaternion" if norm[i] == 0 else f"quaternion norm {norm[i]:.6g} is not within {QUAT_NORM_TOLERANCE} of 1"
            raise InputError(what, source=src, row=i + 1, column=f"{s}_qw..{s}_qz")
    for kind, data in (("acc", rec.acc), ("gyr", rec.gyr)):
        for s, v in data.items():
            v = np.asarray(v)
            if v.shape != (T, 3):
                raise InputError(f"{kind} must have shape ({T}, 3), got {v.shape}", source=src, column=f"{s}_{kind}")


def resolve_sensor_names(found: Iterable[str], default: Mapping[str, str], sensor_map: Mapping[str, str] | None,
                         source: str, what: str, require: bool = True) -> dict[str, str]:
    """Pick the name in the file of each sensor: sensor -> name.

    Entries of ``sensor_map`` (file name -> sensor) win over ``default``; two names of
    one sensor at the same level are ambiguous. With ``require``, every sensor must
    be found.
    """
    found = list(dict.fromkeys(found))
    user = dict(sensor_map or {})
    for name, s in user.items():
        if s not in SENSORS:
            raise InputError(f"sensor_map maps {name!r} to {s!r}, not one of {', '.join(SENSORS)}", source=source)
        if name not in found:
            raise InputError(f"sensor_map names {what} {name!r}, which is not in the file; "
                             f"{what}s found: {', '.join(found) or 'none'}", source=source)
    chosen: dict[str, str] = {}
    for level in (user, default):
        picked: dict[str, str] = {}
        for name in found:
            s = level.get(name)
            if s is None or s in chosen:
                continue
            if s in picked:
                raise InputError(f"{what}s {picked[s]!r} and {name!r} both give sensor {s}; "
                                 "choose one with sensor_map", source=source)
            picked[s] = name
        chosen.update(picked)
    for s in SENSORS if require else ():
        if s not in chosen:
            expected = [n for n, t in {**default, **user}.items() if t == s]
            raise InputError(f"no {what} for sensor {s} (expected {' or '.join(map(repr, expected))}); "
                             f"{what}s found: {', '.join(found) or 'none'}", source=source)
    return chosen
