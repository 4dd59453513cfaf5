"""Motion-capture suits that record segment orientations (BVH, MVNX) as a `Recording`.

A suit (Xsens, Noitom, Rokoko, an optical system) exports each body segment's orientation,
not a sensor's. The readers (:mod:`dualarm.mocap.bvh`, :mod:`dualarm.mocap.mvnx`) hand
this module, per frame, the world rotation of the trunk and of each arm segment, and the
trunk-local directions "up" (pelvis to chest) and "left" (right shoulder to left shoulder).

Each arm segment becomes one of our six "sensors" with orientation

    R_GI(t) = C  R_T(t)^T  R_S(t)

the segment's rotation relative to the trunk T, in the body frame G of the calibration
(x forward, y left, z up) through ``C``, the constant rotation from trunk-local axes to G
built from the two anatomical directions. Why relative to the trunk: the file's world frame
(Y-up or Z-up, any heading) and the person turning or leaning then cannot change a
shoulder angle; a suit has the trunk segment that IMUs on the arms alone lack. The
segment's own axis convention does not matter: it is a constant "mounting" that the
calibration pose (``--calib-pose``: ``npose`` or ``tpose``) removes, as for IMUs.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping

import numpy as np
from scipy.spatial.transform import Rotation

from dualarm.errors import InputError
from dualarm.mocap.recording import ARMS, SEGMENTS, SENSORS, Recording, resolve_sensor_names, sensor_name

_SIDES = {"left": ("left", "l"), "right": ("right", "r")}
# Normalised segment names per segment and side spelling ({w}: left/right, {s}: l/r), as
# CMU, Mixamo, Rokoko and Noitom (LeftArm, LeftForeArm, LeftHand), Xsens MVN
# (LeftUpperArm), Poser/DAZ (lShldr, lForeArm, lHand) and 3ds Max Biped (Bip01 L UpperArm)
# name the bones.
_BONE_NAMES = {
    "upper_arm": ("{w}arm", "{w}upperarm", "{w}uparm", "{s}shldr", "{s}upperarm", "upperarm{s}",
                  "bip01{s}upperarm"),
    "forearm": ("{w}forearm", "{w}lowerarm", "{s}forearm", "{s}lowerarm", "forearm{s}", "lowerarm{s}",
                "bip01{s}forearm"),
    "hand": ("{w}hand", "{s}hand", "hand{s}", "bip01{s}hand"),
}
# Skeletons that name the joint at a bone's root instead (LeftShoulder, LeftElbow, LeftWrist,
# with the clavicle as LeftCollar): used for an arm only when none of its bone names matches,
# since CMU's LeftShoulder is the clavicle.
_JOINT_NAMES = {"upper_arm": ("{w}shoulder",), "forearm": ("{w}elbow",), "hand": ("{w}wrist",)}
#: Example spellings for messages.
EXAMPLE_NAMES = {"upper_arm": "LeftArm, LeftUpperArm or lShldr", "forearm": "LeftForeArm or LeftLowerArm",
                 "hand": "LeftHand"}


def normalise_name(name: str) -> str:
    """A segment name without namespace prefix, case, spaces or punctuation:
    ``'mixamorig:LeftForeArm' -> 'leftforearm'``, ``'Bip01 L UpperArm' -> 'bip01lupperarm'``."""
    return re.sub(r"[^a-z0-9]", "", name.rsplit(":", 1)[-1].lower())


def _scheme(patterns: Mapping[str, tuple[str, ...]]) -> dict[str, str]:
    """Normalised name -> sensor for one naming scheme."""
    out = {}
    for arm in ARMS:
        w, s = _SIDES[arm]
        for seg in SEGMENTS:
            for pattern in patterns[seg]:
                out[pattern.format(w=w, s=s)] = sensor_name(arm, seg)
    return out


def match_segments(names: Iterable[str], sensor_map: Mapping[str, str] | None,
                   source: str) -> dict[str, str]:
    """The file's segment of each sensor: sensor -> segment name as spelled in the file.

    Args:
        names: the segment (or BVH joint) names of the file.
        sensor_map: file's segment name -> sensor, for skeletons named otherwise; wins
            over the default naming.

    Raises:
        InputError: a sensor has no segment, or two segments give one sensor.
    """
    names = list(names)
    bones, joints = _scheme(_BONE_NAMES), _scheme(_JOINT_NAMES)
    found = {n: t for n in names if (t := bones.get(normalise_name(n)))}
    for arm in ARMS:  # an arm named by its joints: only when none of its bones is named
        if not any(t.startswith(arm) for t in found.values()):
            found.update({n: t for n in names if (t := joints.get(normalise_name(n))) and t.startswith(arm)})
    chosen = resolve_sensor_names(names, found, sensor_map, source, "segment", require=False)
    for s in SENSORS:
        if s not in chosen:
            arm, seg = s.split("_", 1)
            example = EXAMPLE_NAMES[seg].replace("Left", arm.capitalize())
            raise InputError(f"no segment for sensor {s} (a name like {example}); segments found: "
                             f"{', '.join(names)}; name it with --sensor-map NAME={s}", source=source)
    return chosen


def trunk_to_body(up: np.ndarray, left: np.ndarray, source: str) -> np.ndarray:
    """``C`` (3, 3): trunk-local coordinates -> body frame G (x forward, y left, z up).

    Args:
        up: (3,) trunk-local direction from the pelvis to the chest (any length).
        left: (3,) trunk-local direction from the right to the left shoulder.

    Raises:
        InputError: a direction is zero or the two are nearly parallel.
    """
    up, left = np.asarray(up, dtype=float), np.asarray(left, dtype=float)
    nu, nl = np.linalg.norm(up), np.linalg.norm(left)
    if not (np.isfinite(nu) and np.isfinite(nl)) or nu < 1e-9 or nl < 1e-9:
        raise InputError("cannot find the body's axes: the pelvis and chest, or the two shoulders, "
                         "are at the same place", source=source)
    z = up / nu
    y = left - (left @ z) * z
    if np.linalg.norm(y) < 0.2 * nl:
        raise InputError("cannot find the body's axes: the shoulder line is nearly along the spine",
                         source=source)
    y /= np.linalg.norm(y)
    x = np.cross(y, z)
    return np.stack([x, y, z])  # rows: the body axes in trunk coordinates


def segment_recording(time: np.ndarray, trunk: np.ndarray, segments: Mapping[str, np.ndarray],
                      body: np.ndarray, source: str) -> Recording:
    """The `Recording` of a suit: each arm segment relative to the trunk, in the body frame.

    Args:
        time: (T,) s.
        trunk: (T, 3, 3) world rotation of the trunk segment (chest), any world frame.
        segments: sensor -> (T, 3, 3) world rotation of its segment, same world frame.
        body: ``C`` (3, 3) from :func:`trunk_to_body`.

    Returns:
        A Recording with ``quat[S] = C R_T^T R_S`` (scalar first).
    """
    lead = body @ np.swapaxes(trunk, -1, -2)
    quat = {s: Rotation.from_matrix(lead @ segments[s]).as_quat(scalar_first=True) for s in SENSORS}
    return Recording(np.asarray(time, dtype=float), quat, source=source)
