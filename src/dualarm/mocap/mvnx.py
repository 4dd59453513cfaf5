"""Read Xsens MVN exports (``.mvnx``) as a `Recording` of the six arm segments.

MVNX is XML: ``<subject frameRate=...>`` holds ``<segments>`` (``<segment label="LeftUpperArm"
id=...>``, in the order the frames use) and ``<frames>``, whose ``type="normal"`` frames each
hold ``<orientation>`` (4 numbers per segment, a scalar-first quaternion of the segment in
Xsens' global frame, Z up) and ``<position>`` (3 per segment, m); ``time`` is in ms. The
header frames (``identity``, ``tpose``, ...) are skipped.

Why the standard library and not an MVNX package: the packages on PyPI (``mvnx`` 0.2,
``mvnx-parser`` 0.0.4) are small, young wrappers around the same ElementTree parse that
load the whole file and give bare tracebacks on a bad frame; ``xml.etree.iterparse``
streams a file of any length in constant memory, its expat (2.4 and later) refuses entity
expansion bombs, and it lets each error name the frame.

The trunk is the ``T8`` segment; its "up" is the mean trunk-local direction from ``Pelvis``
to ``T8``, its "left" from the right to the left upper arm, over all frames. Without
positions, Xsens' own segment axes (x forward, y left, z up) are taken.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from dualarm.errors import InputError, require_file
from dualarm.mocap.recording import SENSORS, Recording
from dualarm.mocap.segments import match_segments, segment_recording, trunk_to_body

#: The segments besides the arms that the reader needs.
TRUNK, PELVIS = "T8", "Pelvis"


def read_mvnx(path: str | os.PathLike, *, sensor_map: Mapping[str, str] | None = None) -> Recording:
    """Read an ``.mvnx`` file.

    Args:
        path: the file.
        sensor_map: file's segment label -> sensor, for labels other than Xsens'
            (``LeftUpperArm``, ``LeftForeArm``, ``LeftHand``, ...).

    Returns:
        The recording, one sample per normal frame: each arm segment's orientation relative
        to T8, in the body frame (x forward, y left, z up).

    Raises:
        InputError: naming the file and, where it applies, the frame (1-based, normal frames).
    """
    source = str(path)
    require_file(path)
    p = Path(path)
    labels: list[str] = []
    rate = None
    times, quats, positions = [], [], []
    try:
        for _, el in ET.iterparse(p, events=("end",)):
            tag = el.tag.rsplit("}", 1)[-1]
            if tag == "segment" and el.get("label") is not None:
                labels.append(el.get("label"))
                el.clear()
            elif tag == "subject":
                rate = el.get("frameRate")
            elif tag == "frame":
                if el.get("type", "normal") == "normal":
                    n = len(quats) + 1
                    times.append(el.get("time"))
                    quats.append(_numbers(el, "orientation", 4 * len(labels), source, n, required=True))
                    positions.append(_numbers(el, "position", 3 * len(labels), source, n, required=False))
                el.clear()
    except ET.ParseError as e:
        raise InputError(f"not valid XML: {e}", source=source, row=e.position[0]) from None
    except OSError as e:
        raise InputError(f"cannot read file ({type(e).__name__}: {e.strerror or e})", source=source) from None
    if not labels:
        raise InputError("no <segment label=...> in <segments>: not an MVNX file", source=source)
    if not quats:
        raise InputError("no frames of type normal", source=source)

    chosen = match_segments(labels, sensor_map, source)
    index = {label: k for k, label in enumerate(labels)}
    if TRUNK not in index:
        raise InputError(f"no segment {TRUNK!r} (the chest) to measure the arms from; segments: "
                         f"{', '.join(labels)}", source=source)
    q = np.stack(quats).reshape(len(quats), len(labels), 4)
    R = {label: _rotations(q[:, k], source, label) for label, k in index.items()
         if label == TRUNK or label in chosen.values()}
    trunk = R[TRUNK]
    body = _body(trunk, positions, index, chosen, labels, source)
    time = _time(times, rate, len(quats), source)
    return segment_recording(time, trunk, {s: R[chosen[s]] for s in SENSORS}, body, source)


def _numbers(frame, name: str, count: int, source: str, n: int, required: bool) -> np.ndarray | None:
    """The ``count`` numbers of child element ``name`` of a frame (None if optional and absent)."""
    child = next((c for c in frame if c.tag.rsplit("}", 1)[-1] == name), None)
    if child is None or not (child.text or "").strip():
        if required:
            raise InputError(f"frame {n} has no <{name}>", source=source, row=n)
        return None
    try:
        values = np.array(child.text.split(), dtype=float)
    except ValueError:
        bad = next(v for v in child.text.split() if not _is_number(v))
        raise InputError(f"<{name}> of frame {n}: not a number: {bad!r}", source=source, row=n) from None
    if values.size != count:
        raise InputError(f"<{name}> of frame {n} has {values.size} numbers, {count} expected "
                         f"({count // (4 if name == 'orientation' else 3)} segments)", source=source, row=n)
    if not np.isfinite(values).all():
        raise InputError(f"<{name}> of frame {n} holds NaN or infinity", source=source, row=n)
    return values


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def _rotations(q: np.ndarray, source: str, label: str) -> np.ndarray:
    """(T, 4) scalar-first quaternions of one segment -> (T, 3, 3); near-unit norm required."""
    norm = np.linalg.norm(q, axis=1)
    bad = np.flatnonzero(np.abs(norm - 1.0) > 1e-3)
    if bad.size:
        raise InputError(f"segment {label}: quaternion norm {norm[bad[0]]:.6g} is not 1",
                         source=source, row=int(bad[0]) + 1)
    return Rotation.from_quat(q, scalar_first=True).as_matrix()   # finite: _numbers checked


def _body(trunk: np.ndarray, positions: list, index: Mapping[str, int], chosen: Mapping[str, str],
          labels: list[str], source: str) -> np.ndarray:
    """C from the mean trunk-local pelvis->T8 and right->left upper-arm directions."""
    if any(p is None for p in positions) or PELVIS not in index:
        return np.eye(3)  # Xsens segment axes: x forward, y left, z up
    pos = np.stack(positions).reshape(len(positions), len(labels), 3)

    def local(a: str, b: str) -> np.ndarray:  # mean of R_T^T (p_b - p_a)
        return np.einsum("tji,tj->i", trunk, pos[:, index[b]] - pos[:, index[a]]) / len(trunk)

    return trunk_to_body(local(PELVIS, TRUNK), local(chosen["right_upper_arm"], chosen["left_upper_arm"]),
                         source)


def _time(times: list, rate, frames: int, source: str) -> np.ndarray:
    """Seconds: each frame's ``time`` (ms), else index / ``frameRate``."""
    if all(t is not None for t in times):
        try:
            return np.array(times, dtype=float) / 1000.0
        except ValueError:
            k = next(i for i, t in enumerate(times) if not _is_number(t))
            raise InputError(f"frame {k + 1}: time={times[k]!r} is not a number", source=source, row=k + 1) from None
    try:
        hz = float(rate)
    except (TypeError, ValueError):
        raise InputError("frames have no time and the subject no frameRate", source=source) from None
    if not (np.isfinite(hz) and hz > 0):
        raise InputError(f"frameRate must be a positive number, got {rate!r}", source=source)
    return np.arange(frames) / hz
