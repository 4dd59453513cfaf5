"""Labels files: when each sub-task of each demonstration happens.

The file is CSV with one header row and the columns

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
"""

from __future__ import annotations

import csv
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dualarm.errors import InputError, require_file
from dualarm.task import ARMS, SUBTASKS

#: Columns of a labels file; ``arm`` may be left out.
LABEL_COLUMNS = ("demo", "arm", "subtask", "start_s", "end_s")
#: Values of the ``arm`` column.
LABEL_ARMS = ("left", "right", "both")

_SUB = {name: k for k, name in enumerate(SUBTASKS)}


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
    require_file(path, "labels file")
    p = Path(path)
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
