"""Demonstration folders as Baxter joint trajectories: each recording through the mapping
(:func:`dualarm.mocap.mapping.map_recording`), an optional zero-phase low-pass filter on the
human joint angles, then the Baxter joint vector (wrapped and clipped to the limits).

Angles are radians and times seconds.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dualarm.demos.formats import DEMO_EXTENSIONS, LABELS_NAME, demo_files, file_sha256, read_grip_events
from dualarm.demos.labels import DemoLabels, check_windows_in_recording, read_labels
from dualarm.errors import InputError

#: Default cut-off (Hz) of the low-pass filter on the joint angles before Eq. 12: the usual
#: choice for human arm movement; removes sensor noise and tremor, keeps the motion.
DEFAULT_LOWPASS_HZ = 6.0


@dataclass(frozen=True)
class DemoJoints:
    """One demonstration as Baxter joint trajectories.

    Attributes:
        name: the demonstration's name (file name without extension).
        time: (T,) s after the first sample.
        q: (T, 14) Baxter joint angles (rad), ``JOINT_COLUMNS``, inside Baxter's limits.
        grip: (T, 2) int gripper events (1 = closed) of the left and right hand, or None.
        source: the recording's path.
        sha256: hex digest of the recording file, or "" when not from a file.
    """

    name: str
    time: np.ndarray
    q: np.ndarray
    grip: np.ndarray | None = None
    source: str = "<demo>"
    sha256: str = ""


def lowpass(time: np.ndarray, q: np.ndarray, cutoff_hz: float | None, source: str = "<demo>") -> np.ndarray:
    """Zero-phase low-pass filter of joint angles (2nd-order Butterworth run forward and back).

    Args:
        time: (T,) s, nearly uniform (the mean rate is used).
        q: (T, N) angles, rad, continuous in time (not wrapped).
        cutoff_hz: cut-off frequency, Hz; None or 0 returns ``q`` unchanged.
    Returns:
        (T, N) filtered angles, rad.
    Raises:
        InputError: the cut-off is not below the Nyquist frequency, or the recording is too short.
    """
    q = np.asarray(q, dtype=float)
    if not cutoff_hz:
        return q
    from scipy.signal import butter, sosfiltfilt

    rate = (len(time) - 1) / (time[-1] - time[0]) if len(time) > 1 else float("nan")
    if not np.isfinite(rate) or cutoff_hz >= rate / 2:
        raise InputError(f"low-pass cut-off {cutoff_hz:g} Hz must be below half the sampling rate "
                         f"({rate:.3g} Hz)", source=source)
    sos = butter(2, cutoff_hz, fs=rate, output="sos")
    if len(time) <= 3 * (2 * len(sos) + 1):
        raise InputError(f"recording too short to filter ({len(time)} samples)", source=source)
    return sosfiltfilt(sos, q, axis=0)


def baxter_joints(time: np.ndarray, q_human: np.ndarray, lowpass_hz: float | None = DEFAULT_LOWPASS_HZ,
                  source: str = "<demo>") -> np.ndarray:
    """Human joint angles (T, 14) rad -> optionally low-passed -> Baxter joint vector (T, 14) rad."""
    from dualarm.mocap.retarget import to_baxter

    return to_baxter(lowpass(time, q_human, lowpass_hz, source)).q


@dataclass(frozen=True)
class MappingOptions:
    """How recordings become joint angles (see ``dualarm mocap joints``).

    Attributes:
        calib_seconds: length of the zero-pose calibration window, s.
        calib_start: its start, s after the first sample.
        calib_pose: the pose held in the window, "npose" (the zero pose) or "tpose".
        heading: "auto" or "off" (heading-offset correction).
        lowpass_hz: cut-off of the zero-phase low-pass filter on the joint angles, Hz; 0 for none.
    """

    calib_seconds: float = 1.0
    calib_start: float = 0.0
    heading: str = "auto"
    lowpass_hz: float = DEFAULT_LOWPASS_HZ
    calib_pose: str = "npose"


def load_demo(path: str | os.PathLike, name: str | None = None,
              options: MappingOptions = MappingOptions(), with_grip: bool = False) -> DemoJoints:
    """Read one recording and map it to Baxter joint angles (calibrate, extract, filter, retarget)."""
    from dualarm.mocap.io import read_recording
    from dualarm.mocap.mapping import map_recording

    path = Path(path)
    rec = read_recording(path)
    result = map_recording(rec, calib_seconds=options.calib_seconds, calib_start=options.calib_start,
                           heading=options.heading, calib_pose=options.calib_pose)
    time = rec.time - rec.time[0]
    q = baxter_joints(time, result.joints.q, options.lowpass_hz, str(path))
    grip = read_grip_events(path) if with_grip else None
    if grip is not None and len(grip) != len(time):
        raise InputError(f"gripper columns have {len(grip)} rows, the recording {len(time)}", source=str(path))
    return DemoJoints(name or path.name.split(".")[0], time, q, grip, str(path), file_sha256(path))


def load_demo_dir(demo_dir: str | os.PathLike, labels_path: str | os.PathLike | None = None,
                  options: MappingOptions = MappingOptions(), *, require_labels: bool = True,
                  with_grip: bool = False, progress: bool = False
                  ) -> tuple[list[DemoJoints], dict[str, DemoLabels]]:
    """Every recording of a folder as Baxter joint angles, with its labels.

    Args:
        demo_dir: folder of recordings (see :func:`demo_files`).
        labels_path: labels file; default ``demo_dir/labels.csv``.
        options: the mapping options.
        require_labels: False reads no labels (an empty dict is returned), e.g. before
            automatic segmentation.
        with_grip: also read the gripper-event columns of CSV recordings.
        progress: a tqdm bar on stderr.
    Raises:
        InputError: a labels row names a demo with no recording, a recording has no labels,
            a window ends after its recording, or anything the readers reject.
    """
    labels_path = Path(demo_dir) / LABELS_NAME if labels_path is None else Path(labels_path)
    files = demo_files(demo_dir, exclude=[labels_path])
    labels: dict[str, DemoLabels] = {}
    if require_labels:
        labels = read_labels(labels_path)
        unknown = [d for d in labels if d not in files]
        if unknown:
            lab = labels[unknown[0]]
            raise InputError(f"demo {unknown[0]!r} has no recording in {demo_dir} (looked for "
                             f"{unknown[0]}{{{','.join(DEMO_EXTENSIONS)}}})", source=lab.source,
                             row=int(lab.rows.min()) or None, column="demo")
        unlabelled = [d for d in files if d not in labels]
        if unlabelled:
            raise InputError(f"recording {files[unlabelled[0]].name} has no labels; add rows for demo "
                             f"{unlabelled[0]!r} or move the file out of the folder", source=str(labels_path))
    items = list(files.items())
    if progress:
        import sys

        from tqdm import tqdm
        items = tqdm(items, desc="mapping", unit="demo", file=sys.stderr)
    demos = []
    for name, path in items:
        demo = load_demo(path, name, options, with_grip)
        if require_labels:
            rate = (len(demo.time) - 1) / demo.time[-1] if demo.time[-1] > 0 else float("nan")
            check_windows_in_recording(labels[name], float(demo.time[-1]), rate)
        demos.append(demo)
    return demos, labels
