"""One call from a `Recording` to human joint angles and the Baxter joint vector."""

from __future__ import annotations

from dataclasses import dataclass
import warnings

from dualarm.errors import InputError
from dualarm.mocap.heading import HeadingEstimate, detect_and_correct, twist_mountings
from dualarm.mocap.joint_angles import (DEFAULT_CALIB_SECONDS, Calibration, JointAngles,
                                        calibrate, calibration_pose_rotation, calibration_window,
                                        joint_angles)
from dualarm.mocap.recording import Recording
from dualarm.mocap.retarget import Retargeted, to_baxter

HEADING_MODES = ("auto", "off")


@dataclass(frozen=True)
class MappingResult:
    """Everything the mapping stage produces for one recording.

    Attributes:
        joints: human joint angles (T, 14) rad and residuals (T, 4) rad.
        robot: Baxter joint vector (T, 14) rad and the clipped fraction per joint.
        calibration: the sensor mountings and the window they came from.
        heading: heading-offset estimates (empty when heading correction is off).
    """

    joints: JointAngles
    robot: Retargeted
    calibration: Calibration
    heading: list[HeadingEstimate]


def map_recording(rec: Recording, *, calib_seconds: float = DEFAULT_CALIB_SECONDS,
                  calib_start: float = 0.0, heading: str = "auto", calib_pose: str = "npose") -> MappingResult:
    """Calibrate on the first ``calib_seconds``, fix heading offsets, extract and retarget.

    Args:
        rec: IMU recording of both arms; the person holds ``calib_pose`` (standing,
            facing +x) from ``calib_start`` for ``calib_seconds``.
        calib_seconds: length of the calibration window, s.
        calib_start: start of the calibration window, s after the first sample.
        calib_pose: the pose held in the window, ``npose`` (the zero pose) or ``tpose``
            (arms out to the sides; :func:`dualarm.mocap.joint_angles.calibration_pose_rotation`).
        heading: ``'auto'`` corrects the sensor heading offsets, the arm's facing and
            the forearm twist found from the elbow and wrist hinge constraints (see
            :mod:`dualarm.mocap.heading`); ``'off'`` uses the orientations as given.
    """
    if heading not in HEADING_MODES:
        raise InputError(f"heading must be one of {', '.join(HEADING_MODES)}, got {heading!r}")
    calibration_window(rec, calib_seconds, calib_start)  # fail early, before any heavy work
    calibration_pose_rotation("left", calib_pose)      # an unknown pose, likewise
    estimates: list[HeadingEstimate] = []
    if heading == "auto":
        with warnings.catch_warnings():  # the stillness warning comes once, from the final calibration
            warnings.simplefilter("ignore")
            rec, estimates = detect_and_correct(rec, calib_seconds, calib_start, calib_pose)
    calib = twist_mountings(calibrate(rec, calib_seconds, calib_start, calib_pose), estimates)
    joints = joint_angles(rec, calib)
    return MappingResult(joints, to_baxter(joints.q), calib, estimates)
