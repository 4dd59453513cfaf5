"""Raw accelerometer + gyroscope samples -> sensor orientation quaternions (6D IMU fusion)."""

from __future__ import annotations

import numpy as np

from dualarm.errors import InputError

#: Accepted values of ``method`` in :func:`orientation_from_imu`; the first is the default.
METHODS: tuple[str, ...] = ("vqf", "madgwick", "mahony", "fusion")

#: Standard gravity, m/s^2 (imufusion takes accelerations in g).
GRAVITY = 9.80665


def _check_samples(name: str, value, n_rows: int | None = None) -> np.ndarray:
    """``value`` as a C-contiguous (T, 3) float64 array; InputError naming ``name`` and the row if not."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"not a numeric array ({exc})", column=name) from None
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"expected shape (T, 3), got {arr.shape}", column=name)
    if arr.shape[0] == 0:
        raise InputError("no samples (T = 0)", column=name)
    if n_rows is not None and arr.shape[0] != n_rows:
        raise InputError(f"has {arr.shape[0]} rows but 'acc' has {n_rows}", column=name)
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"non-finite value {arr[i].tolist()}", row=i + 1, column=name)
    return np.ascontiguousarray(arr)


def _tilt_quaternion(acc0: np.ndarray) -> np.ndarray:
    """Zero-heading orientation whose vertical, seen from the sensor, is along ``acc0``."""
    from scipy.spatial.transform import Rotation

    norm = np.linalg.norm(acc0)
    if norm == 0.0:
        return np.array([1.0, 0.0, 0.0, 0.0])
    # R maps sensor -> global; we want R @ (acc0/|acc0|) = e_z, i.e. R^T e_z = acc0/|acc0|.
    rot, _ = Rotation.align_vectors([[0.0, 0.0, 1.0]], [acc0 / norm])
    return rot.as_quat(scalar_first=True)


def _vqf(acc: np.ndarray, gyr: np.ndarray, rate_hz: float) -> np.ndarray:
    import vqf

    out = vqf.offlineVQF(gyr, acc, None, 1.0 / rate_hz)  # C-contiguous float64 required
    return np.asarray(out["quat6D"], dtype=np.float64)  # w, x, y, z


def _ahrs(acc: np.ndarray, gyr: np.ndarray, rate_hz: float, name: str) -> np.ndarray:
    from ahrs.filters import Madgwick, Mahony  # ahrs quaternions are w, x, y, z

    cls = Madgwick if name == "madgwick" else Mahony
    return np.asarray(cls(gyr=gyr, acc=acc, frequency=rate_hz).Q, dtype=np.float64)


def _imufusion(acc: np.ndarray, gyr: np.ndarray, rate_hz: float) -> np.ndarray:
    import imufusion

    ahrs = imufusion.Ahrs()
    ahrs.set_settings(imufusion.AhrsSettings(sample_rate=rate_hz))
    ahrs.set_sample_period(1.0 / rate_hz)
    # imufusion's start-up phase holds the heading fixed for its first 3 s, which would
    # hide real rotation about the vertical; start instead from the first sample's tilt.
    ahrs.skip_startup()
    ahrs.set_quaternion(_tilt_quaternion(acc[0]))
    gyr_dps = np.rad2deg(gyr)  # imufusion wants deg/s and g
    acc_g = acc / GRAVITY
    out = np.empty((len(acc), 4))
    for i in range(len(acc)):
        ahrs.update_no_magnetometer(gyr_dps[i], acc_g[i])
        out[i] = ahrs.get_quaternion()  # w, x, y, z (NWU, z up: the default convention)
    return out


def orientation_from_imu(acc: np.ndarray, gyr: np.ndarray, rate_hz: float, *,
                         method: str = "vqf") -> np.ndarray:
    """Orientation of the sensor frame in a z-up global frame from raw IMU samples.

    This is 6D fusion (no magnetometer): the inclination (where "up" is, seen from
    the sensor) is observable through gravity, but the heading (rotation about the
    global vertical) is not: it starts at an arbitrary value and may drift over time
    with gyroscope bias. Compare headings only within one call, and use
    heading-independent quantities (e.g. ``R.T @ [0, 0, 1]``) against other sources.

    Args:
        acc: (T, 3) accelerometer samples in m/s^2, sensor frame (reads about
            +9.81 along the sensor's up-pointing axis at rest).
        gyr: (T, 3) gyroscope samples in rad/s, sensor frame.
        rate_hz: sampling rate in Hz (uniform sampling).
        method: ``"vqf"`` (default: offline VQF, Laidig & Seel 2023, acausal, with
            rest detection and gyroscope bias estimation), ``"madgwick"`` or
            ``"mahony"`` (the ``ahrs`` package, default gains) or ``"fusion"``
            (``imufusion``, x-io Fusion). The last three are causal and are here
            so that a comparison can use the same entry point.

    Returns:
        (T, 4) unit quaternions, scalar first (w, x, y, z), each the rotation from
        the sensor frame to the global frame (``R @ v_sensor = v_global``).

    Raises:
        InputError: bad shape, non-finite sample (naming ``'acc'`` or ``'gyr'``
            and the 1-based row), bad ``rate_hz`` or unknown ``method``.
    """
    if method not in METHODS:
        raise InputError(f"unknown fusion method {method!r}; choose one of {', '.join(METHODS)}",
                         column="method")
    try:
        rate = float(rate_hz)
    except (TypeError, ValueError):
        raise InputError(f"rate_hz must be a number, got {rate_hz!r}", column="rate_hz") from None
    if not (np.isfinite(rate) and rate > 0):
        raise InputError(f"rate_hz must be positive and finite, got {rate_hz!r}", column="rate_hz")
    acc = _check_samples("acc", acc)
    gyr = _check_samples("gyr", gyr, n_rows=acc.shape[0])

    if method == "vqf":
        quat = _vqf(acc, gyr, rate)
    elif method in ("madgwick", "mahony"):
        quat = _ahrs(acc, gyr, rate, method)
    else:
        quat = _imufusion(acc, gyr, rate)
    return quat / np.linalg.norm(quat, axis=1, keepdims=True)
