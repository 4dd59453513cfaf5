"""Read and write IMU recordings (CSV, OpenSim ``.sto``, MATLAB ``.mat``) as :class:`Recording` values;
read motion-capture suits' segment orientations (BVH, Xsens MVNX) the same way."""

from __future__ import annotations

import csv
import gzip
import io
import os
from collections.abc import Callable, Mapping
from itertools import repeat
from pathlib import Path

import numpy as np

from dualarm.atomic import atomic_open
from dualarm.errors import InputError, require_file
from dualarm.mocap.recording import ARMS, SEGMENTS, SENSORS, Recording, resolve_sensor_names, sensor_name

#: Accepted file name endings, matched case-insensitively.
EXTENSIONS: tuple[str, ...] = (".csv", ".csv.gz", ".sto", ".mat", ".bvh", ".mvnx")

# Column suffixes of the CSV format: quaternion (scalar first), accelerometer, gyroscope.
_Q, _A, _G = ("_qw", "_qx", "_qy", "_qz"), ("_ax", "_ay", "_az"), ("_gx", "_gy", "_gz")

# OpenSim/OpenSense IMU frame names on the Rajagopal-type arm models.
_OPENSIM_BONES = {"upper_arm": ("humerus",), "forearm": ("radius", "ulna"), "hand": ("hand",)}
_OPENSIM_SIDE = {"left": "l", "right": "r"}
#: Column names :func:`write_sto` gives the six sensors.
STO_NAMES: dict[str, str] = {
    sensor_name(a, g): f"{_OPENSIM_BONES[g][0]}_{_OPENSIM_SIDE[a]}_imu" for a in ARMS for g in SEGMENTS
}


def _own_names() -> dict[str, str]:
    return {s: s for s in SENSORS}


def _sto_default_map() -> dict[str, str]:
    names = _own_names()
    for arm in ARMS:
        for seg in SEGMENTS:
            for bone in _OPENSIM_BONES[seg]:
                stem = f"{bone}_{_OPENSIM_SIDE[arm]}"
                names[stem] = names[stem + "_imu"] = sensor_name(arm, seg)
    return names


def _mat_default_map() -> dict[str, str]:
    # The qmt example data names sensors segment_side ("upper_arm_left").
    names = _own_names()
    names.update({f"{seg}_{arm}": sensor_name(arm, seg) for arm in ARMS for seg in SEGMENTS})
    return names


# --------------------------------------------------------------------------- reading


def read_recording(path: str | os.PathLike, *, sensor_map: Mapping[str, str] | None = None) -> Recording:
    """Read a recording, choosing the reader by the file name's extension.

    Args:
        path: a ``.csv``, ``.csv.gz``, ``.sto`` or ``.mat`` file of IMU orientations, or a
            ``.bvh`` or ``.mvnx`` file of a suit's segments (:mod:`dualarm.mocap.segments`).
        sensor_map: file's name for a sensor -> one of :data:`SENSORS`; overrides the
            default naming of each format (see the readers).

    Raises:
        InputError: unknown extension, missing file, or anything the reader rejects.
    """
    name = Path(path).name.lower()
    # Longest ending first so that ".csv.gz" is not taken for something else.
    ext = next((e for e in sorted(EXTENSIONS, key=len, reverse=True) if name.endswith(e)), None)
    if ext is None:
        raise InputError(f"unknown file type; accepted extensions: {', '.join(EXTENSIONS)}", source=str(path))
    from dualarm.mocap.bvh import read_bvh
    from dualarm.mocap.mvnx import read_mvnx

    reader = {".csv": read_csv, ".csv.gz": read_csv, ".sto": read_sto, ".mat": read_mat,
              ".bvh": read_bvh, ".mvnx": read_mvnx}[ext]
    return reader(path, sensor_map=sensor_map)


def read_csv(path: str | os.PathLike, *, sensor_map: Mapping[str, str] | None = None) -> Recording:
    """Read a CSV recording (optionally gzip-compressed, ``.csv.gz``).

    Format: one header row, then one row per sample. Columns: ``time`` (s, strictly
    increasing) and, for each sensor ``S`` in :data:`SENSORS`, ``S_qw, S_qx, S_qy, S_qz``
    (orientation of the sensor frame in the global frame, scalar first, norm within
    1e-3 of 1). Optional ``S_ax, S_ay, S_az`` (m/s^2) and ``S_gx, S_gy, S_gz`` (rad/s)
    fill ``acc``/``gyr`` when all three are present; a sensor without quaternion
    columns but with both gets its orientation by sensor fusion. Other columns are
    ignored. Cells are plain (no quoting). Blank lines are skipped; rows in messages
    count data rows from 1.

    Args:
        path: the file.
        sensor_map: column prefix in the file -> sensor name, for files whose
            columns are not named after :data:`SENSORS`.

    Returns:
        The recording, T samples: ``quat[S]`` (T, 4), ``acc[S]``/``gyr[S]`` (T, 3).

    Raises:
        InputError: naming the file and, where it applies, the row and column.
    """
    source = str(path)
    lines = _read_text(path).splitlines()
    if not lines or not lines[0].strip():
        raise InputError("empty file: no header row", source=source)
    header = [c.strip() for c in next(csv.reader(lines[:1]))]
    rows = [line for line in lines[1:] if line.strip()]
    if not rows:
        raise InputError("no data rows after the header", source=source)

    found = {c[:-3] for c in header if c[-3:] in _Q + _A + _G}
    prefix = resolve_sensor_names(found, _own_names(), sensor_map, source, "column prefix", require=False)
    plan: dict[str, dict[str, list[str]]] = {}  # sensor -> kind -> its columns
    for s in SENSORS:
        p = prefix.get(s, s)
        cols = {kind: [p + x for x in sfx] for kind, sfx in (("quat", _Q), ("acc", _A), ("gyr", _G))}
        have = {kind: all(c in header for c in cs) for kind, cs in cols.items()}
        fusable = have["acc"] and have["gyr"]
        partial = any(c in header for c in cols["quat"])
        if not have["quat"] and (partial or not fusable):
            missing = next(c for c in cols["quat"] if c not in header)
            hint = "" if partial else f" (nor all of {p}_ax..{p}_az and {p}_gx..{p}_gz to compute it by sensor fusion)"
            raise InputError(f"missing column{hint}", source=source, column=missing)
        plan[s] = {kind: cs for kind, cs in cols.items() if have[kind]}

    needed = ["time"] + [c for s in SENSORS for cs in plan[s].values() for c in cs]
    for c in needed:
        if c not in header:
            raise InputError("missing column", source=source, column=c)
        if header.count(c) > 1:
            raise InputError("column appears more than once in the header", source=source, column=c)
    data = _parse_floats(rows, header, source, usecols=[header.index(c) for c in needed])
    col = dict(zip(needed, data.T))
    tables = {kind: {s: np.column_stack([col[c] for c in plan[s][kind]]) for s in SENSORS if kind in plan[s]}
              for kind in ("quat", "acc", "gyr")}
    return _assemble(source, col["time"], **tables,
                     label=lambda s, kind: f"{prefix.get(s, s)}_{kind[0]}x..{prefix.get(s, s)}_{kind[0]}z")


def read_sto(path: str | os.PathLike, *, sensor_map: Mapping[str, str] | None = None) -> Recording:
    """Read an OpenSim quaternion table (``.sto``, as written by OpenSense).

    Format: header lines up to a line ``endheader``; a tab-separated column header whose
    first column is ``time``; then tab-separated rows whose sensor cells each hold one
    quaternion ``w,x,y,z``. Default column names: OpenSim IMU frames
    (``humerus_r_imu``, ``radius_r_imu`` or ``ulna_r_imu``, ``hand_r_imu`` and ``_l_``
    for the left arm, ``_imu`` optional) or the names in :data:`SENSORS`.

    Args:
        path: the file.
        sensor_map: column name -> sensor name; wins over the default names.

    Returns:
        The recording, T samples, ``quat[S]`` (T, 4); no raw data.

    Raises:
        InputError: naming the file and, where it applies, the row and column.
    """
    source = str(path)
    lines = _read_text(path).splitlines()
    end = next((i for i, line in enumerate(lines) if line.strip() == "endheader"), None)
    if end is None:
        raise InputError("no 'endheader' line: not an OpenSim .sto file", source=source)
    if end + 1 >= len(lines) or not lines[end + 1].strip():
        raise InputError("no column header line after 'endheader'", source=source)
    header = [c.strip() for c in lines[end + 1].rstrip().split("\t")]
    if header[0] != "time":
        raise InputError("the first column must be 'time'", source=source, column=header[0])
    rows = [line.rstrip() for line in lines[end + 2:] if line.strip()]
    if not rows:
        raise InputError("no data rows after the column header", source=source)
    names = resolve_sensor_names(header[1:], _sto_default_map(), sensor_map, source, "column")
    idx = [header.index(names[s]) for s in SENSORS]

    # Flatten each row to "time,w,x,y,z,w,x,y,z,..." so one fast numeric parse does all.
    flat = []
    for r, line in enumerate(rows, start=1):
        cells = line.split("\t")
        if len(cells) != len(header):
            raise InputError(f"row has {len(cells)} cells, the header {len(header)}", source=source, row=r)
        for j in idx:
            if cells[j].count(",") != 3:
                raise InputError(f"expected 4 comma-separated numbers w,x,y,z, got {cells[j]!r}",
                                 source=source, row=r, column=header[j])
        flat.append(",".join([cells[0], *(cells[j] for j in idx)]))
    flat_names = ["time"] + [f"{header[j]} ({c})" for j in idx for c in "wxyz"]
    data = _parse_floats(flat, flat_names, source)
    quat = {s: data[:, 1 + 4 * k: 5 + 4 * k] for k, s in enumerate(SENSORS)}
    return _assemble(source, data[:, 0], quat, {}, {}, label=lambda s, kind: names[s])


def read_mat(path: str | os.PathLike, *, sensor_map: Mapping[str, str] | None = None) -> Recording:
    """Read a MATLAB ``.mat`` recording (v5/v7; not v7.3/HDF5).

    Format: a time vector ``t`` (or ``time``, s) and one struct per sensor with fields
    ``acc`` (T, 3) m/s^2, ``gyr`` (T, 3) rad/s and ``quat`` (T, 4, scalar first). A
    struct without ``quat`` but with ``acc`` and ``gyr`` gets its orientation by sensor
    fusion. Default struct names: those in :data:`SENSORS` or segment first
    (``upper_arm_left``, as in the qmt example data). Other variables are ignored.

    Args:
        path: the file.
        sensor_map: variable name -> sensor name; wins over the default names.

    Returns:
        The recording, T samples, with ``acc``/``gyr`` where the structs have them.

    Raises:
        InputError: naming the file and, where it applies, the variable and field.
    """
    from scipy.io import loadmat

    source = str(path)
    require_file(path)
    try:
        m = loadmat(path, squeeze_me=True, struct_as_record=False)
    except NotImplementedError:  # scipy's answer to HDF5-based v7.3 files
        raise InputError("MATLAB v7.3 (HDF5) files are not supported; save with -v7", source=source) from None
    except Exception as e:  # loadmat fails in many ways on a corrupt file; all mean the same
        raise InputError(f"not a readable MATLAB .mat file ({type(e).__name__}: {e})", source=source) from None
    variables = [k for k in m if not k.startswith("__")]
    tname = next((k for k in ("t", "time") if k in m), None)
    if tname is None:
        raise InputError(f"no time vector 't' or 'time'; variables found: {', '.join(variables) or 'none'}",
                         source=source)
    time = _mat_array(m[tname], source, tname)
    if time.ndim != 1:
        raise InputError(f"time must be a vector, got shape {time.shape}", source=source, column=tname)

    names = resolve_sensor_names(variables, _mat_default_map(), sensor_map, source, "variable")
    tables: dict[str, dict[str, np.ndarray]] = {"quat": {}, "acc": {}, "gyr": {}}
    for s, var in names.items():
        fields = getattr(m[var], "_fieldnames", None)
        if fields is None:
            raise InputError("expected a struct with fields acc, gyr, quat", source=source, column=var)
        for kind, width in (("quat", 4), ("acc", 3), ("gyr", 3)):
            if kind in fields:
                a = np.atleast_2d(_mat_array(getattr(m[var], kind), source, f"{var}.{kind}"))
                if a.shape != (time.shape[0], width):
                    raise InputError(f"expected shape ({time.shape[0]}, {width}) to match '{tname}', got {a.shape}",
                                     source=source, column=f"{var}.{kind}")
                tables[kind][s] = a
        if s not in tables["quat"] and not (s in tables["acc"] and s in tables["gyr"]):
            raise InputError("no field 'quat' (nor both 'acc' and 'gyr' for sensor fusion); "
                             f"fields: {', '.join(fields)}", source=source, column=f"{var}.quat")
    return _assemble(source, time, **tables, label=lambda s, kind: f"{names[s]}.{kind}")


# --------------------------------------------------------------------------- writing


def write_csv(rec: Recording, path: str | os.PathLike) -> None:
    """Write ``rec`` in the format :func:`read_csv` reads, atomically, exact to the bit.

    Columns: ``time``, the four quaternion columns of each sensor in :data:`SENSORS`
    order, then ``S_ax..S_az`` and ``S_gx..S_gz`` for the sensors that have raw data.
    A name ending in ``.gz`` is gzip-compressed.
    """
    header, cols = ["time"], [rec.time[:, None]]
    for s in SENSORS:
        header += [s + x for x in _Q]
        cols.append(rec.quat[s])
    for s in SENSORS:
        for kind, sfx in (("acc", _A), ("gyr", _G)):
            if s in getattr(rec, kind):
                header += [s + x for x in sfx]
                cols.append(getattr(rec, kind)[s])
    write_table_csv(path, header, np.hstack(cols))


def write_table_csv(path: str | os.PathLike, header: list[str], data: np.ndarray) -> None:
    """Write a numeric table as CSV atomically, 17 significant digits (exact round trip).

    Args:
        path: target file; a name ending in ``.gz`` is gzip-compressed.
        header: N column names.
        data: (rows, N) numbers.

    Raises:
        ValueError: ``data`` does not have N columns.
        InputError: the file cannot be written.
    """
    data = np.asarray(data, dtype=float)
    if data.ndim != 2 or data.shape[1] != len(header):
        raise ValueError(f"data must have shape (rows, {len(header)}), got {data.shape}")
    head = _csv_line(header)
    _atomic_write(path, head, ",".join(["%.17g"] * len(header)) + "\n", data)


def write_sto(rec: Recording, path: str | os.PathLike) -> None:
    """Write the orientations of ``rec`` as an OpenSim quaternion table, atomically.

    Columns are the OpenSim IMU names of :data:`STO_NAMES` (``humerus_r_imu``, ...);
    values carry 17 significant digits, so :func:`read_sto` gives back the same bits.
    """
    rate = rec.rate_hz if np.isfinite(rec.rate_hz) else 0.0
    head = (f"DataRate={rate:.6f}\nDataType=Quaternion\nversion=3\nOpenSimVersion=4.5\nendheader\n"
            + "\t".join(["time"] + [STO_NAMES[s] for s in SENSORS]) + "\n")
    rowfmt = "\t".join(["%.17g"] + [",".join(["%.17g"] * 4)] * len(SENSORS)) + "\n"
    _atomic_write(path, head, rowfmt, np.hstack([rec.time[:, None]] + [rec.quat[s] for s in SENSORS]))


# --------------------------------------------------------------------------- helpers


def _read_text(path: str | os.PathLike) -> str:
    """The whole file as text; gunzipped when its name ends in ``.gz``."""
    require_file(path)
    opener = gzip.open if str(path).lower().endswith(".gz") else open
    try:
        # utf-8-sig drops a byte-order mark (spreadsheet exports) that would rename 'time';
        # undecodable bytes become U+FFFD and surface as non-numeric cells, with a row.
        with opener(path, "rt", encoding="utf-8-sig", errors="replace", newline="") as f:
            return f.read()
    except (OSError, EOFError) as e:
        raise InputError(f"cannot read file ({type(e).__name__}: {e})", source=str(path)) from None


def _parse_floats(lines: list[str], names: list[str], source: str,
                  usecols: list[int] | None = None) -> np.ndarray:
    """Parse comma-separated rows into a (rows, len(usecols or names)) float array.

    The fast C parser does the work; only when it fails is the text scanned in Python
    to name the row and column at fault.
    """
    n = len(names)
    if set(map(str.count, lines, repeat(","))) != {n - 1}:  # cheap check; locate only on failure
        bad = next(i for i, line in enumerate(lines) if line.count(",") != n - 1)
        raise InputError(f"row has {lines[bad].count(',') + 1} cells, the header {n}", source=source, row=bad + 1)
    try:
        return np.loadtxt(lines, delimiter=",", usecols=usecols, comments=None, ndmin=2, dtype=float)
    except ValueError as e:
        for i, line in enumerate(lines):
            cells = line.split(",")
            for j in usecols if usecols is not None else range(n):
                try:
                    float(cells[j])
                except ValueError:
                    raise InputError(f"not a number: {cells[j].strip()!r}", source=source,
                                     row=i + 1, column=names[j]) from None
        raise InputError(f"cannot read the numbers ({e})", source=source) from None


def _assemble(source: str, time: np.ndarray, quat: dict[str, np.ndarray], acc: dict[str, np.ndarray],
              gyr: dict[str, np.ndarray], label: Callable[[str, str], str]) -> Recording:
    """Build the validated Recording; sensors without ``quat`` are fused from acc + gyr.

    ``label(sensor, kind)`` names a sensor's data in the file, for messages.
    """
    time = np.asarray(time, dtype=float)
    need = [s for s in SENSORS if s not in quat]
    if need:
        # Fusion needs a sound time axis for its rate: let Recording judge it, with the
        # usual messages, on placeholder identity orientations.
        Recording(time=time, quat=dict.fromkeys(SENSORS, np.broadcast_to([1.0, 0.0, 0.0, 0.0], (time.size, 4))),
                  source=source)
        if time.size < 2:
            raise InputError("sensor fusion needs at least 2 samples", source=source)
        rate = (time.size - 1) / (time[-1] - time[0])  # mean rate; fusion assumes even sampling
        from dualarm.mocap.fusion import orientation_from_imu  # lazy: only raw-data files need it

        quat = dict(quat)
        for s in need:
            for kind, data in (("acc", acc[s]), ("gyr", gyr[s])):
                bad = np.flatnonzero(~np.isfinite(data).all(axis=1))
                if bad.size:
                    raise InputError(f"{kind} is NaN or infinite; sensor fusion needs every sample",
                                     source=source, row=int(bad[0]) + 1, column=label(s, kind))
            try:
                quat[s] = np.asarray(orientation_from_imu(acc[s], gyr[s], rate), dtype=float)
            except InputError as e:  # its message lacks the file; add it
                raise InputError(f"sensor fusion of {label(s, 'acc')} and {label(s, 'gyr')} failed: {e}",
                                 source=source) from None
    return Recording(time=time, quat=quat, acc=acc, gyr=gyr, source=source)


def _mat_array(value, source: str, field: str) -> np.ndarray:
    try:
        return np.atleast_1d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise InputError(f"expected numbers, got {type(value).__name__}", source=source, column=field) from None


def _csv_line(cells: list[str]) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(cells)
    return buf.getvalue()


_CHUNK_ROWS = 4096


def _atomic_write(path: str | os.PathLike, head: str, rowfmt: str, data: np.ndarray) -> None:
    """Write ``head`` then each row of ``data`` through ``rowfmt`` to a temporary file
    beside ``path``, then rename it onto ``path``: a crash never leaves half a file."""
    path = Path(path)
    try:
        with atomic_open(path) as raw:
            out = gzip.GzipFile(fileobj=raw, mode="wb", mtime=0) if path.name.lower().endswith(".gz") else raw
            out.write(head.encode())
            for i in range(0, data.shape[0], _CHUNK_ROWS):
                chunk = data[i:i + _CHUNK_ROWS]
                # One % per chunk instead of per row: the formatting is the slow part.
                out.write(((rowfmt * chunk.shape[0]) % tuple(chunk.ravel().tolist())).encode())
            if out is not raw:
                out.close()  # writes the gzip trailer; leaves raw open
    except OSError as e:
        raise InputError(f"cannot write file ({type(e).__name__}: {e.strerror or e})", source=str(path)) from None
