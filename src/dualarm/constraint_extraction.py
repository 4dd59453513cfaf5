"""From labelled demonstrations to a ``ConstraintSet`` (paper Eqs. 11-12), and what to check before training.

Stages, each a plain function over arrays:

* **labels** (:func:`read_labels`, :func:`labels_csv_text`): when each sub-task of each
  demonstration happens. The file is CSV with one header row and the columns

  ``demo,arm,subtask,start_s,end_s``

  - ``demo``: the demonstration's file name without its extension (``demo_03`` for
    ``demo_03.csv.gz``);
  - ``arm``: ``left``, ``right`` or ``both`` (optional column; without it every row is
    ``both``). The environment tracks the sub-task of each arm separately (the left arm may
    already carry its box while the right one still closes its fingers) and the guide reward
    checks each arm's joints against the segment of *its own* sub-task, so the shipped labels
    are per arm; ``both`` is the short form when the arms change sub-task together;
  - ``subtask``: ``reach``, ``grasp`` or ``align``;
  - ``start_s``, ``end_s``: seconds after the recording's first sample (the same clock as
    ``--calib-start``), ``start_s < end_s``.

  Every demonstration needs each of the three sub-tasks exactly once per arm, in the order
  reach, grasp, align, without overlap (gaps are allowed: samples in a gap belong to no
  sub-task), and inside the recording. Bad files raise ``InputError`` naming the file, the
  data row (1-based, header excluded) and the column.
* **joint trajectories** (:func:`load_demo_dir`, :func:`baxter_joints`): each recording
  through the mapping (:func:`dualarm.mocap.mapping.map_recording`), an optional zero-phase
  low-pass filter on the human joint angles, then the Baxter joint vector (wrapped and
  clipped to the limits).
* **Eq. 12** (:func:`demo_ranges`, :func:`combine_ranges`, :func:`extract_constraints`): for
  each segment (a group of sub-tasks) and joint, the per-demonstration range [a, b] over the
  samples of that segment (of the joint's arm), then the minimum of the a's and the maximum
  of the b's over demonstrations. A percentile P > 0 replaces each demonstration's minimum
  and maximum by its P-th and (100-P)-th percentiles (robust to outlying samples); a margin
  widens the result; bounds are finally clipped to Baxter's limits.
* **automatic segmentation** (:func:`segment_demo`): sub-task times from the hand's speed
  and height (Baxter forward kinematics of the joint vector) and, when the recording has
  them, the gripper events; :func:`segmentation_agreement` compares it with labels.
* **analysis** (:func:`width_fractions`, :func:`arm_volume_fractions`,
  :func:`expert_inside_fractions`): how much of Baxter's joint box each segment leaves, and
  how often the scripted expert's own joint angles stay inside.

Angles are radians and times seconds throughout.
"""

from __future__ import annotations

import csv
import gzip
import hashlib
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dualarm.constraints import SUBTASKS, ConstraintSet, parse_segments
from dualarm.errors import InputError
from dualarm.kinematics import ARMS, BAXTER_JOINT_LIMITS, baxter_arm
from dualarm.task import JOINTS_PER_ARM

#: Columns of a labels file; ``arm`` may be left out.
LABEL_COLUMNS = ("demo", "arm", "subtask", "start_s", "end_s")
#: Values of the ``arm`` column.
LABEL_ARMS = ("left", "right", "both")
#: Default cut-off (Hz) of the low-pass filter on the joint angles before Eq. 12: the usual
#: choice for human arm movement; removes sensor noise and tremor, keeps the motion.
DEFAULT_LOWPASS_HZ = 6.0
#: Recording file endings recognised in a demonstration folder.
DEMO_EXTENSIONS = (".csv.gz", ".csv", ".sto", ".mat")

_N_ARM = JOINTS_PER_ARM
_SUB = {name: k for k, name in enumerate(SUBTASKS)}
_LIMITS14 = np.concatenate([BAXTER_JOINT_LIMITS, BAXTER_JOINT_LIMITS])


# --------------------------------------------------------------------------- labels

@dataclass(frozen=True)
class DemoLabels:
    """The sub-task times of one demonstration.

    Attributes:
        demo: the demonstration's name.
        windows: (2, 3, 2) s after the first sample: [arm (left, right), sub-task (reach,
            grasp, align), (start, end)].
        rows: (2, 3) the labels file's data row (1-based) of each window, 0 when not from a file.
        source: the labels file, for messages.
    """

    demo: str
    windows: np.ndarray
    rows: np.ndarray
    source: str = "<labels>"


def _label_error(message: str, source: str, row: int | None = None, column: str | None = None) -> InputError:
    return InputError(message, source=source, row=row, column=column)


def _parse_time(text: str, source: str, row: int, column: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise _label_error(f"expected a number of seconds, got {text!r}", source, row, column) from None
    if not np.isfinite(value):
        raise _label_error(f"expected a finite number of seconds, got {text!r}", source, row, column)
    if value < 0:
        raise _label_error(f"time before the recording's first sample ({value:g} s < 0)", source, row, column)
    return value


def check_windows(demo: str, windows: np.ndarray, rows: np.ndarray | None = None,
                  source: str = "<labels>") -> None:
    """Validate one demonstration's (2, 3, 2) windows: finite, start < end, in order, no overlap.

    Raises:
        InputError: naming ``source``, the demonstration, the arm, the sub-task and the row.
    """
    w = np.asarray(windows, dtype=float)
    if w.shape != (2, 3, 2):
        raise InputError(f"demo {demo!r}: expected windows of shape (2, 3, 2), got {w.shape}", source=source)
    rows = np.zeros((2, 3), dtype=int) if rows is None else np.asarray(rows)
    for a, arm in enumerate(ARMS):
        for n, name in enumerate(SUBTASKS):
            start, end = w[a, n]
            row = int(rows[a, n]) or None
            if not (np.isfinite(start) and np.isfinite(end)):
                raise _label_error(f"demo {demo!r}, {arm} arm, {name}: times must be finite numbers",
                                   source, row)
            if not start < end:
                raise _label_error(f"demo {demo!r}, {arm} arm, {name}: start_s {start:g} is not before "
                                   f"end_s {end:g}", source, row, "end_s")
        for n in range(1, 3):
            prev_end, start = w[a, n - 1, 1], w[a, n, 0]
            if start < prev_end - 1e-9:
                row = int(rows[a, n]) or None
                what = "starts before" if w[a, n, 0] < w[a, n - 1, 0] else "overlaps"
                raise _label_error(f"demo {demo!r}, {arm} arm: {SUBTASKS[n]} ({start:g}-{w[a, n, 1]:g} s) {what} "
                                   f"{SUBTASKS[n - 1]} ({w[a, n - 1, 0]:g}-{prev_end:g} s); the sub-tasks must "
                                   f"follow each other in the order {', '.join(SUBTASKS)} without overlap",
                                   source, row, "start_s")


def read_labels(path: str | os.PathLike) -> dict[str, DemoLabels]:
    """Read and validate a labels file (format in the module docstring).

    Returns:
        demo name -> :class:`DemoLabels`, in the order the demos first appear.

    Raises:
        InputError: unreadable file, missing column, unknown arm or sub-task, a time that is
            not a number or negative, start not before end, a sub-task given twice or
            missing, sub-tasks out of order or overlapping; naming the file, row and column.
    """
    source = str(path)
    p = Path(path)
    if not p.exists():
        raise InputError("labels file not found", source=source)
    if p.is_dir():
        raise InputError("is a directory, not a labels file", source=source)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"cannot read labels file: {e}", source=source) from None
    lines = [line for line in text.splitlines() if line.strip()]
    if not lines:
        raise InputError("empty labels file: expected the header " + ",".join(LABEL_COLUMNS), source=source)
    header = [c.strip().lower().replace("-", "") for c in next(csv.reader(lines[:1]))]
    for required in ("demo", "subtask", "start_s", "end_s"):
        if required not in header:
            raise InputError(f"missing column (the header must be {','.join(LABEL_COLUMNS)}; "
                             f"'arm' may be left out)", source=source, column=required)
    if len(set(header)) != len(header):
        dup = next(c for c in header if header.count(c) > 1)
        raise InputError("column given twice in the header", source=source, column=dup)
    col = {name: header.index(name) for name in LABEL_COLUMNS if name in header}
    if len(lines) == 1:
        raise InputError("no label rows after the header", source=source)

    windows: dict[str, np.ndarray] = {}
    rows: dict[str, np.ndarray] = {}
    for r, cells in enumerate(csv.reader(lines[1:]), start=1):
        cells = [c.strip() for c in cells]
        if len(cells) != len(header):
            raise InputError(f"row has {len(cells)} cells, the header {len(header)}", source=source, row=r)
        demo = cells[col["demo"]]
        if not demo:
            raise InputError("empty demo name", source=source, row=r, column="demo")
        arm = cells[col["arm"]].lower() if "arm" in col else "both"
        if arm not in LABEL_ARMS:
            raise InputError(f"unknown arm {cells[col['arm']]!r}; expected one of {', '.join(LABEL_ARMS)}",
                             source=source, row=r, column="arm")
        sub = cells[col["subtask"]].lower()
        if sub not in _SUB:
            raise InputError(f"unknown sub-task {cells[col['subtask']]!r}; expected one of {', '.join(SUBTASKS)}",
                             source=source, row=r, column="subtask")
        start = _parse_time(cells[col["start_s"]], source, r, "start_s")
        end = _parse_time(cells[col["end_s"]], source, r, "end_s")
        if not start < end:
            raise InputError(f"start_s {start:g} is not before end_s {end:g}", source=source, row=r, column="end_s")
        w = windows.setdefault(demo, np.full((2, 3, 2), np.nan))
        rw = rows.setdefault(demo, np.zeros((2, 3), dtype=int))
        for a in ((0, 1) if arm == "both" else (ARMS.index(arm),)):
            n = _SUB[sub]
            if rw[a, n]:
                raise InputError(f"demo {demo!r}: {sub} of the {ARMS[a]} arm is labelled twice "
                                 f"(rows {rw[a, n]} and {r})", source=source, row=r, column="subtask")
            w[a, n] = (start, end)
            rw[a, n] = r
    out = {}
    for demo, w in windows.items():
        missing = [(ARMS[a], SUBTASKS[n]) for a in range(2) for n in range(3) if not rows[demo][a, n]]
        if missing:
            arm, sub = missing[0]
            raise InputError(f"demo {demo!r}: no {sub} label for the {arm} arm; every demo needs reach, "
                             f"grasp and align for both arms (arm 'both' covers the two)", source=source)
        check_windows(demo, w, rows[demo], source)
        out[demo] = DemoLabels(demo, w, rows[demo], source)
    return out


def labels_csv_text(windows: Mapping[str, np.ndarray]) -> str:
    """The labels file for demo name -> (2, 3, 2) windows (s): one row per demo, arm and sub-task.

    Times are written with 4 decimals (0.1 ms).
    """
    lines = [",".join(LABEL_COLUMNS)]
    for demo, w in windows.items():
        check_windows(demo, w)
        for a, arm in enumerate(ARMS):
            for n, sub in enumerate(SUBTASKS):
                lines.append(f"{demo},{arm},{sub},{w[a, n, 0]:.4f},{w[a, n, 1]:.4f}")
    return "\n".join(lines) + "\n"


def write_labels(path: str | os.PathLike, windows: Mapping[str, np.ndarray]) -> None:
    """Write a labels file atomically (see :func:`labels_csv_text`)."""
    from dualarm.atomic import atomic_open

    text = labels_csv_text(windows)
    with atomic_open(path) as f:
        f.write(text.encode("utf-8"))


def check_windows_in_recording(labels: DemoLabels, duration_s: float, rate_hz: float) -> None:
    """Every window must end by the recording's end (half a sample of slack).

    Raises:
        InputError: naming the labels file, the row, the demonstration and the recording length.
    """
    slack = 0.5 / rate_hz if np.isfinite(rate_hz) and rate_hz > 0 else 1e-9
    late = labels.windows[..., 1] > duration_s + slack
    if late.any():
        a, n = map(int, np.argwhere(late)[0])
        raise InputError(f"demo {labels.demo!r}, {ARMS[a]} arm, {SUBTASKS[n]}: end_s "
                         f"{labels.windows[a, n, 1]:g} is after the end of the recording ({duration_s:g} s)",
                         source=labels.source, row=int(labels.rows[a, n]) or None, column="end_s")


# --------------------------------------------------------------------------- demonstrations

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


def file_sha256(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def demo_files(demo_dir: str | os.PathLike, exclude: Sequence[str | os.PathLike] = ()) -> dict[str, Path]:
    """Recordings in a folder: demo name (file name without extension) -> path, sorted by name.

    Files with other endings are ignored, and so are ``labels.csv``, hidden files and the
    paths in ``exclude`` (e.g. a labels file kept in the folder under another name).

    Raises:
        InputError: the folder is missing or holds no recording, or two files share a name.
    """
    d = Path(demo_dir)
    if not d.is_dir():
        raise InputError("demonstration folder not found" if not d.exists() else "not a folder",
                         source=str(demo_dir))
    skip = {Path(p).resolve() for p in exclude}
    out: dict[str, Path] = {}
    for path in sorted(d.iterdir()):
        lower = path.name.lower()
        ext = next((e for e in DEMO_EXTENSIONS if lower.endswith(e)), None)
        if ext is None or not path.is_file() or lower == "labels.csv" or path.name.startswith(".") \
                or path.resolve() in skip:
            continue
        name = path.name[:-len(ext)]
        if name in out:
            raise InputError(f"two recordings named {name!r}: {out[name].name} and {path.name}",
                             source=str(demo_dir))
        out[name] = path
    if not out:
        raise InputError(f"no recordings ({', '.join(DEMO_EXTENSIONS)}) in the folder", source=str(demo_dir))
    return out


def read_grip_events(path: str | os.PathLike) -> np.ndarray | None:
    """The ``left_grip, right_grip`` columns of a CSV recording as (T, 2) int, or None if absent.

    Raises:
        InputError: a grip cell that is not 0 or 1 (naming the row and column).
    """
    from dualarm.demos import GRIP_COLUMNS

    name = str(path).lower()
    if not (name.endswith(".csv") or name.endswith(".csv.gz")):
        return None
    opener = gzip.open if name.endswith(".gz") else open
    with opener(path, "rt", encoding="utf-8-sig", newline="") as f:
        lines = [line for line in f.read().splitlines() if line.strip()]
    header = [c.strip() for c in next(csv.reader(lines[:1]))]
    if not all(c in header for c in GRIP_COLUMNS):
        return None
    cols = [header.index(c) for c in GRIP_COLUMNS]
    out = np.empty((len(lines) - 1, 2), dtype=np.int64)
    for r, cells in enumerate(csv.reader(lines[1:]), start=1):
        for j, c in enumerate(cols):
            cell = cells[c].strip() if c < len(cells) else ""
            if cell not in ("0", "1", "0.0", "1.0"):
                raise InputError(f"gripper event must be 0 or 1, got {cell!r}", source=str(path), row=r,
                                 column=GRIP_COLUMNS[j])
            out[r - 1, j] = int(float(cell))
    return out


@dataclass(frozen=True)
class MappingOptions:
    """How recordings become joint angles (see ``dualarm mocap joints``).

    Attributes:
        calib_seconds: length of the zero-pose calibration window, s.
        calib_start: its start, s after the first sample.
        heading: "auto" or "off" (heading-offset correction).
        lowpass_hz: cut-off of the zero-phase low-pass filter on the joint angles, Hz; 0 for none.
    """

    calib_seconds: float = 1.0
    calib_start: float = 0.0
    heading: str = "auto"
    lowpass_hz: float = DEFAULT_LOWPASS_HZ


def load_demo(path: str | os.PathLike, name: str | None = None,
              options: MappingOptions = MappingOptions(), with_grip: bool = False) -> DemoJoints:
    """Read one recording and map it to Baxter joint angles (calibrate, extract, filter, retarget)."""
    from dualarm.mocap.io import read_recording
    from dualarm.mocap.mapping import map_recording

    path = Path(path)
    rec = read_recording(path)
    result = map_recording(rec, calib_seconds=options.calib_seconds, calib_start=options.calib_start,
                           heading=options.heading)
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
    labels_path = Path(demo_dir) / "labels.csv" if labels_path is None else Path(labels_path)
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


# --------------------------------------------------------------------------- Eq. 12

def segment_masks(time: np.ndarray, windows: np.ndarray,
                  groups: Sequence[Sequence[str]]) -> np.ndarray:
    """Which samples of each arm belong to each segment.

    Args:
        time: (T,) s after the first sample.
        windows: (2, 3, 2) s, [arm, sub-task, start/end]; a sample at t belongs to a sub-task
            when start <= t <= end (a sample on a shared boundary belongs to both).
        groups: segments as tuples of sub-task names (``parse_segments``).
    Returns:
        (S, 2, T) bool.
    """
    t = np.asarray(time, dtype=float)
    w = np.asarray(windows, dtype=float)
    inside = (t >= w[..., 0, None] - 1e-9) & (t <= w[..., 1, None] + 1e-9)   # (2, 3, T)
    return np.stack([inside[:, [_SUB[n] for n in g]].any(axis=1) for g in groups])


def demo_ranges(q: np.ndarray, masks: np.ndarray, percentile: float = 0.0,
                demo: str = "<demo>") -> tuple[np.ndarray, np.ndarray]:
    """The per-demonstration range [a_{k,m}^n, b_{k,m}^n] of each segment and joint (Eq. 11).

    Args:
        q: (T, 14) joint angles, rad.
        masks: (S, 2, T) bool, samples of each segment per arm (:func:`segment_masks`).
        percentile: P in [0, 50): a = P-th, b = (100 - P)-th percentile of the segment's
            samples; 0 gives the minimum and maximum.
        demo: name for messages.
    Returns:
        lower (S, 14), upper (S, 14), rad.
    Raises:
        InputError: a segment has no sample for an arm.
    """
    q = np.asarray(q, dtype=float)
    S = masks.shape[0]
    lo = np.empty((S, 2 * _N_ARM))
    hi = np.empty((S, 2 * _N_ARM))
    for s in range(S):
        for a in range(2):
            x = q[masks[s, a], _N_ARM * a:_N_ARM * (a + 1)]
            if x.shape[0] == 0:
                raise InputError(f"demo {demo!r}, {ARMS[a]} arm: segment {s + 1} has no samples inside its "
                                 f"labelled times")
            cols = slice(_N_ARM * a, _N_ARM * (a + 1))
            if percentile > 0:
                lo[s, cols], hi[s, cols] = np.percentile(x, [percentile, 100.0 - percentile], axis=0)
            else:
                lo[s, cols], hi[s, cols] = x.min(axis=0), x.max(axis=0)
    return lo, hi


def combine_ranges(lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 12: C_k^n = [min over m of a_{k,m}^n, max over m of b_{k,m}^n].

    Args:
        lower, upper: (M, S, 14) per-demonstration ranges, rad.
    Returns:
        lower (S, 14), upper (S, 14), rad.
    """
    return np.min(lower, axis=0), np.max(upper, axis=0)


def _check_options(percentile: float, margin: float) -> None:
    if not (np.isfinite(percentile) and 0 <= percentile < 50):
        raise InputError(f"percentile: expected a number in [0, 50), got {percentile!r}")
    if not (np.isfinite(margin) and margin >= 0):
        raise InputError(f"margin: expected a non-negative number of radians, got {margin!r}")


def extract_constraints(demos: Sequence[DemoJoints], windows: Mapping[str, np.ndarray],
                        segments: str | Sequence[Sequence[str]] = "reach+grasp,align", *,
                        percentile: float = 0.0, margin: float = 0.0, name: str | None = None,
                        provenance: Mapping | None = None) -> ConstraintSet:
    """Joint-angle constraints of a set of demonstrations (Eq. 12), one box per segment.

    Args:
        demos: M demonstrations as Baxter joint angles (T_m, 14) rad.
        windows: demo name -> (2, 3, 2) sub-task windows, s (or :class:`DemoLabels`).
        segments: how sub-tasks group into segments: "reach+grasp+align" gives C1 (single),
            "reach+grasp,align" gives C2 and C3 (multi); or the parsed tuples.
        percentile: P in [0, 50): robust per-demonstration range (see :func:`demo_ranges`).
        margin: widening of every bound, rad (>= 0).
        name: the set's name; default "single" for one segment, else "multi".
        provenance: stored in the set as-is.
    Returns:
        The ``ConstraintSet``; bounds clipped to Baxter's joint limits.
    """
    groups = parse_segments(segments) if isinstance(segments, str) else tuple(tuple(g) for g in segments)
    _check_options(percentile, margin)
    if not demos:
        raise InputError("no demonstrations to extract constraints from")
    los, his = [], []
    for d in demos:
        if d.name not in windows:
            raise InputError(f"demo {d.name!r} has no labels")
        w = windows[d.name]
        w = w.windows if isinstance(w, DemoLabels) else np.asarray(w, dtype=float)
        lo, hi = demo_ranges(d.q, segment_masks(d.time, w, groups), percentile, d.name)
        los.append(lo)
        his.append(hi)
    lower, upper = combine_ranges(np.stack(los), np.stack(his))
    lower = np.clip(lower - margin, _LIMITS14[:, 0], _LIMITS14[:, 1])
    upper = np.clip(upper + margin, _LIMITS14[:, 0], _LIMITS14[:, 1])
    if name is None:
        name = "single" if len(groups) == 1 else "multi"
    return ConstraintSet(tuple(zip(groups, lower, upper)), name=name, provenance=dict(provenance or {}))


def segments_spec(groups: Sequence[Sequence[str]]) -> str:
    """(("reach", "grasp"), ("align",)) -> "reach+grasp,align"."""
    return ",".join("+".join(g) for g in groups)


def extraction_provenance(demos: Sequence[DemoJoints], labels_file: str | os.PathLike | None,
                          labels_origin: str, options: MappingOptions, segments: str,
                          percentile: float, margin: float) -> dict:
    """The provenance block of an extracted constraints file: demo files and hashes, labels, options."""
    from dualarm import __version__

    prov = {
        "method": "Eq. 12: per segment and joint, the minimum over demonstrations of each one's minimum "
                  "and the maximum of each one's maximum (percentiles when percentile > 0), widened by "
                  "margin, clipped to Baxter's limits",
        "software": f"dualarm {__version__}",
        "demos": [{"file": Path(d.source).name, "sha256": d.sha256} for d in demos],
        "labels": {"origin": labels_origin},
        "options": {"segments": segments, "percentile": float(percentile), "margin_rad": float(margin),
                    "lowpass_hz": float(options.lowpass_hz or 0.0), "calib_seconds": float(options.calib_seconds),
                    "calib_start": float(options.calib_start), "heading": options.heading},
    }
    if labels_file is not None:
        prov["labels"].update({"file": Path(labels_file).name, "sha256": file_sha256(labels_file)})
    return prov


# --------------------------------------------------------------------------- automatic segmentation

#: Distance (m) from Baxter's hand frame (D-H frame 7) to the grip point, along its z axis.
GRIP_OFFSET = 0.13


@dataclass(frozen=True)
class SegmentationOptions:
    """Thresholds of :func:`segment_demo`.

    Attributes:
        smooth_hz: cut-off of the zero-phase low-pass filter on the grip points before their
            speed is taken, Hz (timing is resolved to about a quarter of its period).
        rest_speed: the hand rests (pauses) below this speed, m/s.
        still_speed: a motion starts or ends where the speed crosses this (lower) speed, m/s.
        min_rest_s: shortest rest that counts, s.
        grasp_search_s: with gripper events, the box is where the hand is lowest within
            this long of the gripper's first closing, s.
        reach_m: reach ends when the hand comes within this height of the box (the
            environment's ``reach_threshold``), m.
        lift_m: grasp ends when the hand has risen this much above the box (the
            environment's ``lift_height``), m.
    """

    smooth_hz: float = 2.0
    rest_speed: float = 0.06
    still_speed: float = 0.025
    min_rest_s: float = 0.15
    grasp_search_s: float = 0.5
    reach_m: float = 0.02
    lift_m: float = 0.02


def hand_points(q: np.ndarray) -> np.ndarray:
    """Grip points of both arms through Baxter's forward kinematics.

    Args:
        q: (T, 14) Baxter joint angles, rad.
    Returns:
        (T, 2, 3) positions, m, in Baxter's frame (z up).
    """
    q = np.asarray(q, dtype=float)
    out = np.empty(q.shape[:1] + (2, 3))
    for a, arm in enumerate(ARMS):
        pose = baxter_arm(arm).forward(q[:, _N_ARM * a:_N_ARM * (a + 1)])[:, -1]
        out[:, a] = pose[:, :3, 3] + GRIP_OFFSET * pose[:, :3, 2]
    return out


def _runs(mask: np.ndarray) -> np.ndarray:
    """(R, 2) [first, last] sample index of each run of True."""
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(m)
    return np.stack([np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1], axis=1)


def segment_demo(time: np.ndarray, q: np.ndarray, grip: np.ndarray | None = None, *,
                 calib_end_s: float = 1.0, options: SegmentationOptions = SegmentationOptions(),
                 demo: str = "<demo>") -> np.ndarray:
    """Sub-task windows of one demonstration from the hand's motion (and gripper events).

    Assumes the layout of a reach-grasp-align recording: the zero-pose window, possibly a
    move to a start posture and a pause, then the task, then a pause at the end. Per arm,
    from the grip point p(t) (:func:`hand_points`, low-passed at ``smooth_hz``) and its speed v:

    * rests are runs of at least ``min_rest_s`` with v below ``rest_speed``;
    * the box is where the hand is lowest: after the calibration window, or, when the
      recording has gripper events, within ``grasp_search_s`` of the gripper's first closing;
    * the grasp starts when the hand, going down to the box, comes within ``reach_m`` of
      that height, and ends when it has risen ``lift_m`` above it (the environment's
      reach and lift thresholds);
    * reach starts where the hand sets off before that: the last sample before the grasp's
      preceding motion with v below ``still_speed``;
    * align ends where the hand comes to a stop: the first sample after the last motion
      with v below ``still_speed`` (or the last sample).

    Args:
        time: (T,) s after the first sample.
        q: (T, 14) Baxter joint angles, rad.
        grip: (T, 2) gripper events (1 closed), or None.
        calib_end_s: end of the calibration window, s; nothing starts before it.
    Returns:
        (2, 3, 2) windows, s, [arm, sub-task, start/end].
    Raises:
        InputError: naming the demonstration, when no grasp, lift or start can be found.
    """
    t = np.asarray(time, dtype=float)
    after = t >= calib_end_s
    if after.sum() < 3:
        raise InputError(f"demo {demo!r}: nothing recorded after the calibration window ({calib_end_s:g} s)")
    p = hand_points(q)
    p = lowpass(t, p.reshape(len(t), 6), options.smooth_hz, demo).reshape(p.shape)
    speed = np.linalg.norm(np.gradient(p, t, axis=0), axis=-1)           # (T, 2)
    dt = float(np.median(np.diff(t)))
    min_len = max(1, int(round(options.min_rest_s / dt)))
    first = int(np.argmax(after))
    search = max(1, int(round(options.grasp_search_s / dt)))
    out = np.empty((2, 3, 2))
    for a, arm in enumerate(ARMS):
        v = speed[:, a]
        rest_level, still_level = options.rest_speed, options.still_speed
        runs = _runs((v < rest_level) & after)
        runs = runs[runs[:, 1] - runs[:, 0] + 1 >= min_len]
        height = p[:, a, 2]
        if grip is not None:
            closing = np.flatnonzero(after[1:] & (grip[1:, a] > 0) & (grip[:-1, a] == 0)) + 1
            if closing.size == 0:
                raise InputError(f"demo {demo!r}, {arm} arm: the gripper never closes after the calibration "
                                 f"window")
            lo_i = max(first, int(closing[0]) - search)
            low = lo_i + int(np.argmin(height[lo_i:int(closing[0]) + search + 1]))
        else:
            low = first + int(np.argmin(height[first:]))
        above = np.flatnonzero(height[first:low + 1] > height[low] + options.reach_m)
        g0 = first + int(above[-1]) + 1 if above.size else first
        before = runs[runs[:, 1] < g0]
        if before.shape[0] == 0:
            raise InputError(f"demo {demo!r}, {arm} arm: no pause before the reach")
        off = int(before[-1, 1]) + 1
        still = np.flatnonzero(v[:off] < still_level)
        r0 = int(still[-1]) if still.size and still[-1] >= before[-1, 0] else int(before[-1, 1])
        rise = np.flatnonzero(height[low:] >= height[low] + options.lift_m)
        if rise.size == 0:
            raise InputError(f"demo {demo!r}, {arm} arm: the hand never rises {options.lift_m:g} m after "
                             f"the grasp")
        g1 = low + int(rise[0])
        moving = np.flatnonzero(v[g1:] >= rest_level)
        last_motion = g1 + int(moving[-1]) if moving.size else g1
        stop = np.flatnonzero(v[last_motion:] < still_level)
        a1 = last_motion + int(stop[0]) if stop.size else len(t) - 1
        out[a] = [[t[r0], t[g0]], [t[g0], t[g1]], [t[g1], t[min(max(a1, g1 + 1), len(t) - 1)]]]
    return out


def segmentation_agreement(time: np.ndarray, auto: np.ndarray, labels: np.ndarray) -> dict[str, np.ndarray]:
    """How well automatic windows agree with labelled ones on one demonstration.

    Args:
        time: (T,) s.
        auto, labels: (2, 3, 2) windows, s.
    Returns:
        ``boundary_error_s``: (2, 4) |auto - label| of reach start, grasp start, align start,
        align end per arm (s); ``frame_agreement``: (2,) fraction of the samples inside the
        labelled task (reach start to align end) given the same sub-task by both.
    """
    def boundaries(w):
        return np.stack([w[:, 0, 0], w[:, 1, 0], w[:, 2, 0], w[:, 2, 1]], axis=1)

    def frame_labels(w):
        t = np.asarray(time)
        lab = np.full((2, t.size), -1)
        for n in range(3):
            lab = np.where((t >= w[:, n, 0, None]) & (t < w[:, n, 1, None]), n, lab)
        return lab

    la, ll = frame_labels(auto), frame_labels(labels)
    task = ll >= 0
    agree = ((la == ll) & task).sum(axis=1) / np.maximum(task.sum(axis=1), 1)
    return {"boundary_error_s": np.abs(boundaries(auto) - boundaries(labels)), "frame_agreement": agree}


# --------------------------------------------------------------------------- analysis

def width_fractions(cs: ConstraintSet, limits: np.ndarray = BAXTER_JOINT_LIMITS) -> np.ndarray:
    """(S, 14) width of each segment's range over the width of Baxter's range, per joint."""
    lim = np.concatenate([limits, limits]) if np.shape(limits) == (_N_ARM, 2) else np.asarray(limits)
    span = lim[:, 1] - lim[:, 0]
    return np.stack([(np.clip(s.upper, lim[:, 0], lim[:, 1]) - np.clip(s.lower, lim[:, 0], lim[:, 1])) / span
                     for s in cs.segments])


def arm_volume_fractions(cs: ConstraintSet, limits: np.ndarray = BAXTER_JOINT_LIMITS) -> np.ndarray:
    """(S, 2) fraction of one arm's 7-D joint box (left, right) each segment leaves."""
    w = width_fractions(cs, limits)
    return np.stack([w[:, :_N_ARM].prod(axis=1), w[:, _N_ARM:].prod(axis=1)], axis=1)


def expert_rollouts(episodes: int, seed: int = 1000, progress: bool = False
                    ) -> tuple[np.ndarray, np.ndarray, float]:
    """Joint angles and sub-tasks of the scripted expert over seeded episodes.

    Args:
        episodes: number of episodes (reset seeds ``seed .. seed + episodes - 1``).
    Returns:
        q (N, 14) rad, the joint angles after each step of every episode; subtasks (N, 2),
        each arm's sub-task after that step; the success rate.
    """
    from dualarm.envs import make_core
    from dualarm.envs.rollout import make_policy, run_episode

    env = make_core()
    policy = make_policy("expert", env)
    seeds = range(seed, seed + episodes)
    if progress:
        import sys

        from tqdm import tqdm
        seeds = tqdm(seeds, desc="expert", unit="ep", file=sys.stderr)
    qs, subs, wins = [], [], 0
    try:
        for s in seeds:
            ep = run_episode(env, policy, s)
            qs.append(ep.joint_angles[1:])
            subs.append(ep.subtasks)
            wins += ep.success
    finally:
        env.close()
    return np.concatenate(qs), np.concatenate(subs), wins / episodes


@dataclass(frozen=True)
class InsideReport:
    """How often joint angles stay inside the constraints of their arm's current segment.

    Attributes:
        fraction: (S, 14) for segment s and joint k, the share of rows whose arm (of joint
            k) is in a sub-task of segment s with joint k inside the bounds; NaN where no row is.
        all_joints: (S, 2) the share of those rows with all seven joints of the arm inside
            (what earns an arm the full guide reward +7 c0).
        count: (S, 2) rows per segment and arm.
    """

    fraction: np.ndarray
    all_joints: np.ndarray
    count: np.ndarray


def expert_inside_fractions(cs: ConstraintSet, q: np.ndarray, subtasks: np.ndarray) -> InsideReport:
    """Check joint angles against the segment each arm is in (as the guide reward does).

    Args:
        cs: the constraints.
        q: (N, 14) joint angles, rad.
        subtasks: (N, 2) sub-task index (0 reach, 1 grasp, 2 align) of the left and right arm.
    Returns:
        :class:`InsideReport`.
    """
    subtasks = np.asarray(subtasks)
    inside = cs.inside(q, subtasks[:, 0], subtasks[:, 1])                      # (N, 14)
    seg = cs.segment_of_subtask[subtasks]                                      # (N, 2)
    S = len(cs.segments)
    frac = np.full((S, 2 * _N_ARM), np.nan)
    every = np.full((S, 2), np.nan)
    count = np.zeros((S, 2), dtype=np.int64)
    for s in range(S):
        for a in range(2):
            rows = seg[:, a] == s
            count[s, a] = rows.sum()
            if count[s, a]:
                arm_inside = inside[rows, _N_ARM * a:_N_ARM * (a + 1)]
                frac[s, _N_ARM * a:_N_ARM * (a + 1)] = arm_inside.mean(axis=0)
                every[s, a] = arm_inside.all(axis=1).mean()
    return InsideReport(frac, every, count)
