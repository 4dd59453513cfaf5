"""The files of a demonstration folder: where the shipped set lives, the names inside a
folder, the CSV layout of a recording with gripper events, and content hashes.

A demonstration folder holds one recording per demonstration (``demo_00.csv.gz`` ..., any of
``DEMO_EXTENSIONS``), a labels file ``LABELS_NAME`` (:mod:`dualarm.demos.labels`) and a scene
file ``SCENE_NAME`` (:mod:`dualarm.demos.scene`). The CSV
layout is that of ``dualarm mocap joints`` (``time`` and ``S_qw..S_qz`` per sensor) plus the
gripper events ``GRIP_COLUMNS`` (1 while the hand is closed; other readers ignore them).
"""

from __future__ import annotations

import csv
import gzip
import hashlib
import io
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from dualarm.errors import InputError
from dualarm.mocap.recording import SENSORS, Recording

#: The shipped default demonstration set (10 demonstrations, ``generate_demos(10, seed=0)``).
DEFAULT_DEMO_DIR = Path(__file__).resolve().parents[1] / "data" / "demos"
#: Name of the labels file inside a demonstration folder.
LABELS_NAME = "labels.csv"
#: Name of the scene file inside a demonstration folder (:mod:`dualarm.demos.scene`).
SCENE_NAME = "scene.csv"
#: Columns of the gripper events in a demonstration CSV (1 = hand closed).
GRIP_COLUMNS = ("left_grip", "right_grip")
#: Recording file endings recognised in a demonstration folder.
DEMO_EXTENSIONS = (".csv.gz", ".csv", ".sto", ".mat", ".bvh", ".mvnx")
#: Decimal places of the quaternions in written demonstration files (quantisation 5e-7,
#: far below the sensor noise).
QUAT_DECIMALS = 6


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
        if ext is None or not path.is_file() or lower in (LABELS_NAME, SCENE_NAME) \
                or path.name.startswith(".") \
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


def gzip_bytes(text: str) -> bytes:
    """gzip of ``text`` (UTF-8) with no file name and time stamp 0 in the header: reproducible."""
    buffer = io.BytesIO()
    with gzip.GzipFile(filename="", fileobj=buffer, mode="wb", compresslevel=9, mtime=0) as gz:
        gz.write(text.encode("utf-8"))
    return buffer.getvalue()


def demo_csv_text(rec: Recording, grip: np.ndarray) -> str:
    """The CSV text of a demonstration: time, 24 quaternion columns, ``GRIP_COLUMNS``."""
    header = ["time"] + [f"{s}_q{c}" for s in SENSORS for c in "wxyz"] + list(GRIP_COLUMNS)
    buf = io.StringIO()
    buf.write(",".join(header) + "\n")
    data = np.hstack([rec.time[:, None]] + [rec.quat[s] for s in SENSORS] + [grip])
    fmt = ",".join(["%.9g"] + [f"%.{QUAT_DECIMALS}f"] * (4 * len(SENSORS)) + ["%d"] * 2)
    np.savetxt(buf, data, fmt=fmt)
    return buf.getvalue()
