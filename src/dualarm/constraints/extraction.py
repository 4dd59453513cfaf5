"""Eq. 12: from labelled demonstrations to a ``ConstraintSet``.

For each segment (a group of sub-tasks) and joint, the per-demonstration range [a, b] over
the samples of that segment (of the joint's arm), then the minimum of the a's and the maximum
of the b's over demonstrations. A percentile P > 0 replaces each demonstration's minimum and
maximum by its P-th and (100-P)-th percentiles (robust to outlying samples); a margin widens
the result; bounds are finally clipped to Baxter's limits. Angles in radians, times in seconds.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from dualarm.constraints.constraint_set import ConstraintSet, parse_segments
from dualarm.demos.formats import DEFAULT_DEMO_DIR, LABELS_NAME, file_sha256
from dualarm.demos.labels import DemoLabels
from dualarm.demos.loading import DemoJoints, MappingOptions, load_demo_dir
from dualarm.demos.segmentation import segment_demos
from dualarm.errors import InputError
from dualarm.kinematics import BAXTER_JOINT_LIMITS
from dualarm.task import ARMS, JOINTS_PER_ARM, SUBTASKS

_N_ARM = JOINTS_PER_ARM
_SUB = {name: k for k, name in enumerate(SUBTASKS)}
_LIMITS14 = np.concatenate([BAXTER_JOINT_LIMITS, BAXTER_JOINT_LIMITS])


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
                    "calib_start": float(options.calib_start), "calib_pose": options.calib_pose,
                    "heading": options.heading},
    }
    if labels_file is not None:
        prov["labels"].update({"file": Path(labels_file).name, "sha256": file_sha256(labels_file)})
    return prov


def constraints_from_folder(demo_dir: str | os.PathLike | None, segments: str, *, name: str | None = None,
                            labels_path: str | os.PathLike | None = None,
                            options: MappingOptions = MappingOptions(), percentile: float = 0.0,
                            margin: float = 0.0, auto_segment: bool = False, use_grip: bool = True,
                            progress: bool = False) -> ConstraintSet:
    """A folder of demonstrations -> its constraints (Eq. 12), with their provenance.

    What ``dualarm constraints extract`` and ``dualarm pipeline`` do.

    Args:
        demo_dir: folder of recordings; None for the shipped set (``DEFAULT_DEMO_DIR``).
        segments: sub-tasks per segment, e.g. "reach+grasp+align" (C1) or "reach+grasp,align"
            (C2 and C3).
        name: name of the set (default: single or multi, by the number of segments).
        labels_path: labels file; default ``demo_dir/LABELS_NAME``.
        options: how recordings become joint angles.
        percentile, margin: see :func:`extract_constraints` (margin in rad).
        auto_segment: sub-task times from :func:`segment_demo` instead of a labels file,
            with the recordings' gripper events unless ``use_grip`` is False.
        progress: a progress bar over the recordings.
    """
    groups = parse_segments(segments)
    spec = segments_spec(groups)
    folder = Path(demo_dir) if demo_dir is not None else DEFAULT_DEMO_DIR
    demos, labels = load_demo_dir(folder, labels_path, options, require_labels=not auto_segment,
                                  with_grip=auto_segment, progress=progress)
    if auto_segment:
        windows = segment_demos(demos, options.calib_start + options.calib_seconds, use_grip)
        labels_file, origin = None, "automatic segmentation (dualarm.demos.segmentation.segment_demo)"
    else:
        windows = {n: lab.windows for n, lab in labels.items()}
        labels_file = Path(labels_path) if labels_path else folder / LABELS_NAME
        origin = "labels file"
    provenance = extraction_provenance(demos, labels_file, origin, options, spec, percentile, margin)
    return extract_constraints(demos, windows, groups, percentile=percentile, margin=margin, name=name,
                               provenance=provenance)
