"""Joint-angle constraint sets (paper Eqs. 11-12) and the segmented guide reward (Eq. 16)."""

from __future__ import annotations

import numbers
import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from dualarm.atomic import atomic_open
from dualarm.errors import InputError
from dualarm.kinematics import BAXTER_JOINT_LIMITS, BAXTER_JOINT_NAMES
from dualarm.task import GUIDED_CONDITIONS, JOINT_COLUMNS, PAPER_C0, SUBTASKS
from dualarm.yaml_io import read_yaml

#: Guide-reward constants c0 per sub-task (reach, grasp, align), from the paper's experiment.
DEFAULT_C0 = PAPER_C0
#: Bounds closer than this (rad) are the same bound in ``ConstraintSet.matches``.
MATCH_ATOL = 1e-9
#: Version of the YAML file layout written by :meth:`ConstraintSet.save`.
SCHEMA_VERSION = 1
#: Conditions with a shipped constraints file (``default_constraints_path``).
DEFAULT_CONDITIONS = GUIDED_CONDITIONS

_N_JOINTS = len(JOINT_COLUMNS)
_N_ARM = len(BAXTER_JOINT_NAMES)
_SUBTASK_INDEX = {name: k for k, name in enumerate(SUBTASKS)}
#: Baxter's limits for both arms, (14, 2) rad.
_LIMITS14 = np.concatenate([BAXTER_JOINT_LIMITS, BAXTER_JOINT_LIMITS])
_LIMITS14.flags.writeable = False
_TOP_KEYS = ("schema_version", "name", "units", "joints", "segments", "provenance")
_REQUIRED_TOP_KEYS = ("schema_version", "units", "joints", "segments")
_SEGMENT_KEYS = ("subtasks", "lower", "upper")
#: Validated c0 tuples -> ((3,) float array, same as Python floats), so the per-step reward
#: skips re-validation.
_C0_CACHE: dict[tuple, tuple[np.ndarray, tuple[float, ...]]] = {}


def default_constraints_path(condition: str) -> Path:
    """The shipped constraints file of a guided condition.

    Both were extracted (Eq. 12) from the shipped default demonstrations
    (``dualarm.demos.formats.DEFAULT_DEMO_DIR``): "single" is C1 (one segment, reach+grasp+align),
    "multi" is C2 (reach+grasp) and C3 (align); see docs/constraints.md.

    Args:
        condition: "single" or "multi".
    Returns:
        Path of ``dualarm/data/constraints/<condition>.yaml`` inside the installed package.
    Raises:
        ValueError: any other condition.
    """
    if condition not in DEFAULT_CONDITIONS:
        raise ValueError(f"condition must be one of {', '.join(DEFAULT_CONDITIONS)} to have default "
                         f"constraints, got {condition!r}")
    return Path(__file__).resolve().parents[1] / "data" / "constraints" / f"{condition}.yaml"


# --------------------------------------------------------------------------- helpers

def _readonly(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


def _is_real(x: Any) -> bool:
    return isinstance(x, (numbers.Real, np.number)) and not isinstance(x, (bool, np.bool_))


def _bounds_array(value: Any, where: str, source: str | None = None) -> np.ndarray:
    """``value`` as a read-only float64 (14,) copy, or InputError naming ``where[i] (joint)``."""
    if isinstance(value, np.ndarray) and value.dtype.kind in "iuf":
        arr = np.array(value, dtype=np.float64)
        if arr.shape != (_N_JOINTS,):
            got = f"{arr.size}" if arr.ndim == 1 else f"an array of shape {arr.shape}"
            raise InputError(f"{where}: expected {_N_JOINTS} values ({JOINT_COLUMNS[0]}..{JOINT_COLUMNS[-1]}), "
                             f"got {got}", source=source)
    else:
        if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, (Sequence, np.ndarray)):
            raise InputError(f"{where}: expected a list of {_N_JOINTS} numbers, got {type(value).__name__}",
                             source=source)
        if len(value) != _N_JOINTS:
            raise InputError(f"{where}: expected {_N_JOINTS} values ({JOINT_COLUMNS[0]}..{JOINT_COLUMNS[-1]}), "
                             f"got {len(value)}", source=source)
        for i, x in enumerate(value):
            if not _is_real(x):
                hint = ""
                if isinstance(x, str):
                    hint = (" (YAML 1.1 reads an exponent float without a decimal point, such as 1e-3, "
                            "as text: write 1.0e-3)")
                raise InputError(f"{where}[{i}] ({JOINT_COLUMNS[i]}): expected a number, got "
                                 f"{type(x).__name__} {x!r}{hint}", source=source)
        arr = np.array([float(x) for x in value], dtype=np.float64)
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        i = int(bad[0])
        raise InputError(f"{where}[{i}] ({JOINT_COLUMNS[i]}): expected a finite number, got {float(arr[i])!r}",
                         source=source)
    return _readonly(arr)


def _subtask_names(value: Any, where: str, source: str | None = None) -> tuple[str, ...]:
    """A segment's sub-task names as a tuple ("reach+grasp" or a sequence of names)."""
    if isinstance(value, str):
        names = [part.strip() for part in value.split("+")]
    elif isinstance(value, Sequence) and not isinstance(value, bytes):
        names = list(value)
    else:
        raise InputError(f"{where}: expected a list of sub-task names from {list(SUBTASKS)}, "
                         f"got {type(value).__name__}", source=source)
    if not names:
        raise InputError(f"{where}: empty; name at least one sub-task from {list(SUBTASKS)}", source=source)
    for i, name in enumerate(names):
        if not isinstance(name, str):
            raise InputError(f"{where}[{i}]: expected a sub-task name, got {type(name).__name__} {name!r}",
                             source=source)
        if name not in _SUBTASK_INDEX:
            raise InputError(f"{where}[{i}]: unknown sub-task {name!r}; known: {', '.join(SUBTASKS)}",
                             source=source)
    return tuple(names)


def _check_segment(subtasks: Any, lower: Any, upper: Any, where: str,
                   source: str | None = None) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """Validate one segment's fields; errors name ``{where}subtasks``, ``{where}lower[i] (joint)``..."""
    names = _subtask_names(subtasks, f"{where}subtasks", source)
    lo = _bounds_array(lower, f"{where}lower", source)
    up = _bounds_array(upper, f"{where}upper", source)
    bad = np.flatnonzero(lo > up)
    if bad.size:
        i = int(bad[0])
        raise InputError(f"{where}lower[{i}] ({JOINT_COLUMNS[i]}) = {float(lo[i])!r} is above "
                         f"{where}upper[{i}] = {float(up[i])!r}", source=source)
    return names, lo, up


def _check_cover(segment_subtasks: Sequence[tuple[str, ...]], where: str = "segments",
                 source: str | None = None) -> None:
    """Each sub-task exactly once, segments in SUBTASKS order, each a contiguous run."""
    first_seen: dict[str, int] = {}
    for s, names in enumerate(segment_subtasks):
        for name in names:
            if name in first_seen:
                other = first_seen[name]
                place = f"{where}[{s}] twice" if other == s else f"{where}[{other}] and {where}[{s}]"
                raise InputError(f"sub-task {name!r} is covered by {place}; each sub-task must be "
                                 f"covered exactly once", source=source)
            first_seen[name] = s
    missing = [name for name in SUBTASKS if name not in first_seen]
    if missing:
        raise InputError(f"sub-task {missing[0]!r} is not covered by any of the {where}; "
                         f"the segments must cover {', '.join(SUBTASKS)} exactly once", source=source)
    k = 0
    for s, names in enumerate(segment_subtasks):
        expected = SUBTASKS[k:k + len(names)]
        if tuple(names) != expected:
            raise InputError(f"{where}[{s}] covers {'+'.join(names)}: segments must follow the sub-task "
                             f"order {' -> '.join(SUBTASKS)}, each a contiguous run (expected "
                             f"{'+'.join(expected)} here)", source=source)
        k += len(names)


def _subtask_index(value: Any, where: str) -> Any:
    """int or name -> int in 0..2; int/str array-likes -> int array."""
    if type(value) is int:
        if 0 <= value < len(SUBTASKS):
            return value
        raise InputError(f"{where}: sub-task index {value} out of range 0..{len(SUBTASKS) - 1}")
    if isinstance(value, str):
        try:
            return _SUBTASK_INDEX[value]
        except KeyError:
            raise InputError(f"{where}: unknown sub-task {value!r}; known: {', '.join(SUBTASKS)}") from None
    if isinstance(value, np.integer):
        return _subtask_index(int(value), where)
    arr = np.asarray(value)
    if arr.dtype.kind in "US":
        flat = [_subtask_index(str(v), where) for v in arr.ravel()]
        return np.array(flat, dtype=np.intp).reshape(arr.shape)
    if arr.dtype.kind not in "iu":
        raise InputError(f"{where}: expected sub-task indices (int) or names, got dtype {arr.dtype}")
    if arr.size and (arr.min() < 0 or arr.max() >= len(SUBTASKS)):
        raise InputError(f"{where}: sub-task index out of range 0..{len(SUBTASKS) - 1}")
    return arr.astype(np.intp, copy=False)


def _c0_values(c0: Any) -> tuple[np.ndarray, tuple[float, ...]]:
    """c0 validated, as a read-only (3,) float array and as Python floats (cached for tuples)."""
    if type(c0) is tuple:
        cached = _C0_CACHE.get(c0)
        if cached is not None:
            return cached
    try:
        arr = np.array(c0, dtype=np.float64)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.shape != (len(SUBTASKS),) or not np.all(np.isfinite(arr)) or not np.all(arr > 0):
        raise InputError(f"c0: expected {len(SUBTASKS)} positive finite numbers, one per sub-task "
                         f"({', '.join(SUBTASKS)}), got {c0!r}")
    values = (_readonly(arr), tuple(arr.tolist()))
    if type(c0) is tuple and len(_C0_CACHE) < 64:
        _C0_CACHE[c0] = values
    return values


def _limits14(limits: Any) -> np.ndarray:
    lim = np.asarray(limits, dtype=np.float64)
    if lim.shape == (_N_ARM, 2):
        lim = np.concatenate([lim, lim])
    if lim.shape != (_N_JOINTS, 2):
        raise InputError(f"limits: expected shape ({_N_ARM}, 2) (one arm, used for both) or "
                         f"({_N_JOINTS}, 2), got {lim.shape}")
    if not np.all(np.isfinite(lim)) or np.any(lim[:, 1] <= lim[:, 0]):
        raise InputError("limits: expected finite [lower, upper] rows with lower < upper")
    return lim


# --------------------------------------------------------------------------- data classes

@dataclass(frozen=True, eq=False)
class ConstraintSegment:
    """Joint-angle box shared by a contiguous run of sub-tasks.

    Attributes:
        subtasks: names from ``SUBTASKS`` this box applies to, in order (a "reach+grasp"
            string is accepted and split).
        lower: (14,) lower bounds a_k (rad), columns ``JOINT_COLUMNS``; read-only float64 copy.
        upper: (14,) upper bounds b_k (rad), same columns; read-only float64 copy.
    """

    subtasks: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray

    def __post_init__(self) -> None:
        names, lo, up = _check_segment(self.subtasks, self.lower, self.upper, "")
        object.__setattr__(self, "subtasks", names)
        object.__setattr__(self, "lower", lo)
        object.__setattr__(self, "upper", up)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ConstraintSegment):
            return NotImplemented
        return (self.subtasks == other.subtasks and np.array_equal(self.lower, other.lower)
                and np.array_equal(self.upper, other.upper))

    def __hash__(self) -> int:
        # + 0.0 maps -0.0 to 0.0, so equal segments hash equal.
        return hash((self.subtasks, (self.lower + 0.0).tobytes(), (self.upper + 0.0).tobytes()))


@dataclass(frozen=True)
class ConstraintSet:
    """Joint-angle constraints C^n (Eq. 12) of the dual-arm task, one box per segment of sub-tasks.

    Each segment is a (14,) box [lower, upper] in rad over ``JOINT_COLUMNS`` (left arm, then
    right arm) applying to a contiguous run of ``SUBTASKS``; together the segments cover every
    sub-task exactly once, in order. The set is immutable and validated on construction
    (``InputError`` naming the field, e.g. ``segments[1].lower[3] (left_e1)``); bounds are not
    clipped to Baxter's limits here (``from_dict``/``load`` clip them, with a warning).

    Attributes:
        segments: the boxes, in sub-task order. Items may also be given as
            ``(subtasks, lower, upper)`` tuples; they are stored as ``ConstraintSegment``.
        name: label of the set, e.g. "C1".
        provenance: free-form mapping (how the set was made), kept as-is, not compared.
        lower_by_subtask: (3, 14) read-only, row k = lower bounds (rad) for ``SUBTASKS[k]``.
        upper_by_subtask: (3, 14) read-only, row k = upper bounds (rad) for ``SUBTASKS[k]``.
        segment_of_subtask: (3,) int, index of the segment covering ``SUBTASKS[k]``.
    """

    segments: tuple[ConstraintSegment, ...]
    name: str = ""
    provenance: dict = field(default_factory=dict, compare=False, repr=False)
    lower_by_subtask: np.ndarray = field(init=False, repr=False, compare=False)
    upper_by_subtask: np.ndarray = field(init=False, repr=False, compare=False)
    segment_of_subtask: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if isinstance(self.segments, (str, bytes, Mapping, ConstraintSegment)) or \
                not isinstance(self.segments, Sequence):
            raise InputError(f"segments: expected a sequence of ConstraintSegment, "
                             f"got {type(self.segments).__name__}")
        if len(self.segments) == 0:
            raise InputError("segments: empty; a constraint set needs at least one segment")
        segments = []
        for s, seg in enumerate(self.segments):
            if not isinstance(seg, ConstraintSegment):
                if isinstance(seg, Mapping):
                    missing = [k for k in _SEGMENT_KEYS if k not in seg]
                    if missing:
                        raise InputError(f"segments[{s}].{missing[0]}: missing")
                    seg = (seg["subtasks"], seg["lower"], seg["upper"])
                if isinstance(seg, (str, bytes)) or not isinstance(seg, Sequence) or len(seg) != 3:
                    raise InputError(f"segments[{s}]: expected a ConstraintSegment or a "
                                     f"(subtasks, lower, upper) triple, got {type(seg).__name__}")
                seg = ConstraintSegment(*_check_segment(*seg, where=f"segments[{s}]."))
            segments.append(seg)
        if not isinstance(self.name, str):
            raise InputError(f"name: expected a string, got {type(self.name).__name__}")
        if not isinstance(self.provenance, Mapping):
            raise InputError(f"provenance: expected a mapping, got {type(self.provenance).__name__}")
        _check_cover([seg.subtasks for seg in segments])
        seg_of = np.empty(len(SUBTASKS), dtype=np.intp)
        for s, seg in enumerate(segments):
            for name in seg.subtasks:
                seg_of[_SUBTASK_INDEX[name]] = s
        lower = np.stack([segments[s].lower for s in seg_of])
        upper = np.stack([segments[s].upper for s in seg_of])
        set_ = object.__setattr__
        set_(self, "segments", tuple(segments))
        set_(self, "provenance", dict(self.provenance))
        set_(self, "lower_by_subtask", _readonly(lower))
        set_(self, "upper_by_subtask", _readonly(upper))
        set_(self, "segment_of_subtask", _readonly(seg_of))
        # (3, 3, 14) tables indexed [left sub-task, right sub-task]: left arm columns from the
        # left's row, right arm columns from the right's row. One lookup per env step.
        lo2 = np.empty((len(SUBTASKS), len(SUBTASKS), _N_JOINTS))
        up2 = np.empty_like(lo2)
        lo2[:, :, :_N_ARM] = lower[:, None, :_N_ARM]
        lo2[:, :, _N_ARM:] = lower[None, :, _N_ARM:]
        up2[:, :, :_N_ARM] = upper[:, None, :_N_ARM]
        up2[:, :, _N_ARM:] = upper[None, :, _N_ARM:]
        set_(self, "_lower_lr", _readonly(lo2))
        set_(self, "_upper_lr", _readonly(up2))

    # ------------------------------------------------------------------ constructors

    @classmethod
    def single(cls, lower: Any, upper: Any, name: str = "C1", provenance: Mapping | None = None) -> ConstraintSet:
        """One (14,) box [lower, upper] (rad) shared by all three sub-tasks."""
        return cls((ConstraintSegment(SUBTASKS, lower, upper),), name=name, provenance=dict(provenance or {}))

    @classmethod
    def from_groups(cls, groups: Mapping[str, tuple[Any, Any]] | Sequence[tuple[Any, Any, Any]],
                    name: str = "", provenance: Mapping | None = None) -> ConstraintSet:
        """Set from groups of sub-tasks, in sub-task order.

        Args:
            groups: ``{"reach+grasp": (lower, upper), "align": (lower, upper)}`` or a list of
                ``(subtasks, lower, upper)`` with subtasks a "reach+grasp" string or a sequence of
                names; lower/upper are (14,) rad over ``JOINT_COLUMNS``.
            name: label of the set.
            provenance: free-form mapping kept as-is.
        """
        if isinstance(groups, Mapping):
            triples = []
            for key, value in groups.items():
                if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) != 2:
                    raise InputError(f"groups[{key!r}]: expected a (lower, upper) pair")
                triples.append((key, value[0], value[1]))
        else:
            triples = list(groups)
        return cls(tuple(triples), name=name, provenance=dict(provenance or {}))

    @classmethod
    def full_range(cls, name: str = "full_range") -> ConstraintSet:
        """Baxter's joint limits (both arms, rad) as one segment covering all sub-tasks."""
        return cls.single(_LIMITS14[:, 0], _LIMITS14[:, 1], name=name)

    # ------------------------------------------------------------------ queries

    def bounds(self, subtask: str | int) -> tuple[np.ndarray, np.ndarray]:
        """(lower (14,), upper (14,)) in rad for ``subtask`` (name or index into SUBTASKS); read-only."""
        k = _subtask_index(subtask, "subtask")
        if not isinstance(k, int):
            raise InputError("subtask: expected one sub-task name or index")
        return self.lower_by_subtask[k], self.upper_by_subtask[k]

    def inside(self, q: Any, subtask_left: Any, subtask_right: Any) -> np.ndarray:
        """Which joints satisfy their constraint C_k^n (Eq. 12); boundaries count as inside.

        Args:
            q: (..., 14) joint angles (rad), columns ``JOINT_COLUMNS`` (left arm q[..., :7]).
            subtask_left: current sub-task of the left arm: index into SUBTASKS or name; an int
                array broadcastable to q.shape[:-1] gives one per row.
            subtask_right: the same for the right arm.
        Returns:
            bool (..., 14): left joints checked against the left arm's sub-task bounds, right
            joints against the right arm's.
        """
        q = np.asarray(q, dtype=np.float64)
        if q.shape[-1:] != (_N_JOINTS,):
            raise InputError(f"q: expected shape (..., {_N_JOINTS}), got {q.shape}")
        sl = _subtask_index(subtask_left, "subtask_left")
        sr = _subtask_index(subtask_right, "subtask_right")
        return (q >= self._lower_lr[sl, sr]) & (q <= self._upper_lr[sl, sr])

    def guide_reward(self, q: Any, subtask_left: Any, subtask_right: Any, c0: Any = DEFAULT_C0) -> np.ndarray:
        """Segmented guide reward r_guide of Eq. 16 for each arm's agent.

        Per arm: sum over its 7 joints of +c0[n] if a_k <= q_k <= b_k (bounds of the segment
        covering the arm's current sub-task n) else -c0[n].

        Args:
            q: (..., 14) joint angles (rad), columns ``JOINT_COLUMNS``.
            subtask_left, subtask_right: each arm's current sub-task (index into SUBTASKS or
                name; int arrays broadcastable to q.shape[:-1] for per-row sub-tasks).
            c0: 3 positive constants, one per sub-task (reach, grasp, align); unitless reward.
        Returns:
            float64 (..., 2): [left reward, right reward]; each in [-7 c0[n], 7 c0[n]].
        """
        c, c_floats = _c0_values(c0)
        sl = _subtask_index(subtask_left, "subtask_left")
        sr = _subtask_index(subtask_right, "subtask_right")
        q = np.asarray(q, dtype=np.float64)
        if q.shape == (_N_JOINTS,) and type(sl) is int and type(sr) is int:
            # Single step: count inside joints per arm on the bytes of the bool mask.
            ok = ((q >= self._lower_lr[sl, sr]) & (q <= self._upper_lr[sl, sr])).tobytes()
            n_left = ok.count(1, 0, _N_ARM)
            n_right = ok.count(1, _N_ARM)
            return np.array((c_floats[sl] * (2 * n_left - _N_ARM), c_floats[sr] * (2 * n_right - _N_ARM)))
        if q.shape[-1:] != (_N_JOINTS,):
            raise InputError(f"q: expected shape (..., {_N_JOINTS}), got {q.shape}")
        ok = (q >= self._lower_lr[sl, sr]) & (q <= self._upper_lr[sl, sr])
        n = ok.reshape(ok.shape[:-1] + (2, _N_ARM)).sum(axis=-1)
        scale = np.stack(np.broadcast_arrays(c[sl], c[sr]), axis=-1)
        return scale * (2 * n - _N_ARM)

    def matches(self, other: "ConstraintSet", atol: float = MATCH_ATOL) -> bool:
        """Same name and segments (sub-tasks, and bounds within ``atol`` rad); provenance aside.

        Re-extracting the same demonstrations can move a bound by an ulp (threaded BLAS sums
        in the mapping), so a comparison asks this rather than for equal bytes.
        """
        return self.name == other.name and len(self.segments) == len(other.segments) and all(
            a.subtasks == b.subtasks and np.allclose(a.lower, b.lower, rtol=0, atol=atol)
            and np.allclose(a.upper, b.upper, rtol=0, atol=atol)
            for a, b in zip(self.segments, other.segments))

    def width_fractions(self, limits: Any = BAXTER_JOINT_LIMITS) -> np.ndarray:
        """Width of each segment's range over the width of the joint's limits.

        Args:
            limits: (7, 2) [lower, upper] per joint of one arm, used for both arms (rad), or
                (14, 2) over ``JOINT_COLUMNS``. Default: Baxter's limits.
        Returns:
            (n_segments, 14) in [0, 1]: (segment width clipped to the limits) / (limit width).
        """
        lim = _limits14(limits)
        lo = np.clip(np.stack([seg.lower for seg in self.segments]), lim[:, 0], lim[:, 1])
        up = np.clip(np.stack([seg.upper for seg in self.segments]), lim[:, 0], lim[:, 1])
        return (up - lo) / (lim[:, 1] - lim[:, 0])

    def volume_fraction(self, limits: Any = BAXTER_JOINT_LIMITS) -> np.ndarray:
        """(n_segments,) fraction of the 14-D joint box (both arms) each segment's box
        occupies: the product of :meth:`width_fractions` over the joints."""
        return self.width_fractions(limits).prod(axis=1)

    # ------------------------------------------------------------------ serialisation

    def to_dict(self) -> dict:
        """Plain mapping in the YAML file layout: schema_version, name, units ("rad"), joints
        (the 14 ``JOINT_COLUMNS``), segments [{subtasks, lower (14 floats), upper (14 floats)}],
        provenance."""
        return {
            "schema_version": SCHEMA_VERSION,
            "name": self.name,
            "units": "rad",
            "joints": list(JOINT_COLUMNS),
            "segments": [{"subtasks": list(seg.subtasks), "lower": seg.lower.tolist(),
                          "upper": seg.upper.tolist()} for seg in self.segments],
            "provenance": dict(self.provenance),
        }

    @classmethod
    def from_dict(cls, d: Any, source: str | os.PathLike | None = None) -> ConstraintSet:
        """Validate a mapping in the ``to_dict`` layout (bounds in rad) and build the set.

        Bounds outside Baxter's joint limits are clipped to them with a UserWarning naming the
        segment and joint. Errors are ``InputError`` with ``source`` and the field named.
        """
        src = None if source is None else str(source)
        if not isinstance(d, Mapping):
            got = "an empty document" if d is None else type(d).__name__
            raise InputError(f"expected a mapping with keys {', '.join(_REQUIRED_TOP_KEYS)}, got {got}",
                             source=src)
        unknown = [k for k in d if k not in _TOP_KEYS]
        if unknown:
            raise InputError(f"{unknown[0]}: unknown field; allowed: {', '.join(_TOP_KEYS)}", source=src)
        for key in _REQUIRED_TOP_KEYS:
            if key not in d:
                raise InputError(f"{key}: missing field", source=src)
        version = d["schema_version"]
        if type(version) is not int:
            raise InputError(f"schema_version: expected an integer, got {type(version).__name__} {version!r}",
                             source=src)
        if version != SCHEMA_VERSION:
            raise InputError(f"schema_version: unsupported version {version}; this program reads "
                             f"version {SCHEMA_VERSION}", source=src)
        name = d.get("name", "")
        if name is None:
            name = ""
        if not isinstance(name, str):
            raise InputError(f"name: expected a string, got {type(name).__name__}", source=src)
        if d["units"] != "rad":
            raise InputError(f"units: expected 'rad', got {d['units']!r}", source=src)
        joints = d["joints"]
        if not isinstance(joints, list) or not all(isinstance(j, str) for j in joints):
            raise InputError(f"joints: expected a list of {_N_JOINTS} joint names, got "
                             f"{type(joints).__name__}", source=src)
        if tuple(joints) != JOINT_COLUMNS:
            if len(joints) != _N_JOINTS:
                detail = f"{len(joints)} names"
            else:
                i = next(i for i, (a, b) in enumerate(zip(joints, JOINT_COLUMNS)) if a != b)
                detail = f"joints[{i}] = {joints[i]!r} where {JOINT_COLUMNS[i]!r} is expected"
            raise InputError(f"joints: expected {list(JOINT_COLUMNS)}, got {detail}", source=src)
        provenance = d.get("provenance")
        if provenance is None:
            provenance = {}
        _check_provenance(provenance, src)
        raw_segments = d["segments"]
        if not isinstance(raw_segments, list):
            raise InputError(f"segments: expected a list, got {type(raw_segments).__name__}", source=src)
        if not raw_segments:
            raise InputError("segments: empty; a constraint set needs at least one segment", source=src)
        segments = []
        for s, raw in enumerate(raw_segments):
            where = f"segments[{s}]"
            if not isinstance(raw, Mapping):
                raise InputError(f"{where}: expected a mapping with keys {', '.join(_SEGMENT_KEYS)}, "
                                 f"got {type(raw).__name__}", source=src)
            unknown = [k for k in raw if k not in _SEGMENT_KEYS]
            if unknown:
                raise InputError(f"{where}.{unknown[0]}: unknown field; allowed: {', '.join(_SEGMENT_KEYS)}",
                                 source=src)
            for key in _SEGMENT_KEYS:
                if key not in raw:
                    raise InputError(f"{where}.{key}: missing field", source=src)
            for key in ("lower", "upper"):
                if not isinstance(raw[key], list):
                    raise InputError(f"{where}.{key}: expected a list of {_N_JOINTS} numbers, got "
                                     f"{type(raw[key]).__name__}", source=src)
            names, lo, up = _check_segment(raw["subtasks"], raw["lower"], raw["upper"], f"{where}.", src)
            lo, up = _clip_to_limits(lo, up, where, src)
            segments.append(ConstraintSegment(names, lo, up))
        _check_cover([seg.subtasks for seg in segments], source=src)
        return cls(tuple(segments), name=name, provenance=dict(provenance))

    def save(self, path: str | os.PathLike) -> None:
        """Write the set as YAML (``to_dict`` layout, floats at repr precision) atomically:
        a temporary file in the same folder, then a rename (``dualarm.atomic``)."""
        path = Path(path)
        text = "# Joint-angle constraint set (dualarm.constraints); angles in rad.\n" + yaml.safe_dump(
            self.to_dict(), sort_keys=False, default_flow_style=None, width=4096, allow_unicode=True)
        with atomic_open(path) as out:
            out.write(text.encode("utf-8"))

    @classmethod
    def load(cls, path: str | os.PathLike) -> ConstraintSet:
        """Read a set written by ``save`` (or by hand in that layout), validated as in ``from_dict``.

        Errors (unreadable file, YAML syntax, missing or mistyped field, wrong schema_version or
        joints, non-numeric bounds) are ``InputError`` with ``source=path`` and the field named.
        """
        src = str(path)
        data = read_yaml(path, "constraint file")
        return cls.from_dict(data, source=src)


def _check_provenance(provenance: Any, source: str | None) -> None:
    """Provenance is free-form; only what the extractor writes is checked where it appears.

    A mapping in ``demos`` (a list) with ``file`` must name it with a non-empty string, and
    any ``sha256`` there or in ``labels`` must be 64 lower-case hexadecimal digits.
    """
    if not isinstance(provenance, Mapping):
        raise InputError(f"provenance: expected a mapping, got {type(provenance).__name__}", source=source)

    def digest(value: Any, where: str) -> None:
        if not (isinstance(value, str) and len(value) == 64 and all(c in "0123456789abcdef" for c in value)):
            raise InputError(f"{where}: expected 64 lower-case hexadecimal digits, got {value!r}", source=source)

    demos = provenance.get("demos")
    if isinstance(demos, list):
        for i, item in enumerate(demos):
            if not isinstance(item, Mapping):
                continue
            if "file" in item and not (isinstance(item["file"], str) and item["file"]):
                raise InputError(f"provenance.demos[{i}].file: expected a file name, got {item['file']!r}",
                                 source=source)
            if "sha256" in item:
                digest(item["sha256"], f"provenance.demos[{i}].sha256")
    labels = provenance.get("labels")
    if isinstance(labels, Mapping) and "sha256" in labels:
        digest(labels["sha256"], "provenance.labels.sha256")


def _clip_to_limits(lo: np.ndarray, up: np.ndarray, where: str,
                    source: str | None) -> tuple[np.ndarray, np.ndarray]:
    """Clip (14,) bounds to Baxter's limits, warning once per segment with every clipped joint."""
    lim_lo, lim_hi = _LIMITS14[:, 0], _LIMITS14[:, 1]
    lo_c = np.clip(lo, lim_lo, lim_hi)
    up_c = np.clip(up, lim_lo, lim_hi)
    changed = []
    for key, old, new in (("lower", lo, lo_c), ("upper", up, up_c)):
        for i in np.flatnonzero(old != new):
            changed.append(f"{key}[{i}] ({JOINT_COLUMNS[i]}) {float(old[i])!r} -> {float(new[i])!r}")
    if changed:
        prefix = f"{source}: " if source is not None else ""
        warnings.warn(f"{prefix}{where}: bounds outside Baxter's joint limits clipped: {'; '.join(changed)}",
                      UserWarning, stacklevel=3)
        return _readonly(lo_c), _readonly(up_c)
    return lo, up


def parse_segments(spec: str) -> tuple[tuple[str, ...], ...]:
    """Parse a segmentation such as "reach+grasp,align" into (("reach", "grasp"), ("align",)).

    Segments are separated by ",", sub-tasks within one by "+"; together they must cover
    ``SUBTASKS`` exactly once, in order, each segment a contiguous run. Errors: InputError.
    """
    if not isinstance(spec, str):
        raise InputError(f"segments: expected a string such as 'reach+grasp,align', got {type(spec).__name__}")
    if not spec.strip():
        raise InputError("segments: empty; expected e.g. 'reach+grasp,align' or 'reach+grasp+align'")
    groups = []
    for s, part in enumerate(spec.split(",")):
        names = []
        for name in part.split("+"):
            name = name.strip().lower()
            if not name:
                raise InputError(f"segments {spec!r}: empty sub-task name in part {s + 1} ({part.strip()!r})")
            if name not in _SUBTASK_INDEX:
                raise InputError(f"segments {spec!r}: unknown sub-task {name!r}; known: {', '.join(SUBTASKS)}")
            names.append(name)
        groups.append(tuple(names))
    try:
        _check_cover(groups, where="parts")
    except InputError as e:
        raise InputError(f"segments {spec!r}: {e}") from None
    return tuple(groups)


def same_constraints(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """Whether two constraints files hold matching sets (:meth:`ConstraintSet.matches`);
    False when either is missing."""
    if not (Path(a).exists() and Path(b).exists()):
        return False
    return ConstraintSet.load(a).matches(ConstraintSet.load(b))
