"""Figures of joint-angle constraints: demonstrations with their bands, joint-space share, expert inside.

Headless (``matplotlib.figure.Figure``, no pyplot state) and written atomically through
:func:`dualarm.mocap.plots.save_figure`. Radians in, degrees and percentages on the axes.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from dualarm.constraints.analysis import arm_volume_fractions
from dualarm.demos.loading import DemoJoints
from dualarm.constraints.constraint_set import ConstraintSet
from dualarm.task import JOINT_COLUMNS, SUBTASKS
from dualarm.kinematics import ARMS, BAXTER_JOINT_NAMES
from dualarm.mocap.plots import ARM_COLOURS, save_figure
from dualarm.task import JOINTS_PER_ARM

_N_ARM = JOINTS_PER_ARM
_SEGMENT_COLOURS = ("tab:green", "tab:orange", "tab:purple")


def task_phase(time: np.ndarray, windows: np.ndarray) -> np.ndarray:
    """Time -> task phase per arm: sub-task n (reach 0, grasp 1, align 2) runs from n to n + 1.

    Args:
        time: (T,) s.
        windows: (2, 3, 2) s, [arm, sub-task, start/end].
    Returns:
        (2, T) phase, NaN outside the labelled sub-tasks (before reach, after align, in gaps).
    """
    t = np.asarray(time, dtype=float)
    out = np.full((2, t.size), np.nan)
    for a in range(2):
        for n in range(len(SUBTASKS)):
            s, e = windows[a, n]
            inside = (t >= s) & (t <= e)
            out[a, inside] = n + (t[inside] - s) / (e - s)
    return out


def plot_constraints(cs: ConstraintSet, demos: Sequence[DemoJoints], windows: Mapping[str, np.ndarray],
                     path: str | os.PathLike, *, title: str | None = None) -> Path:
    """Every demonstration's joint curves against task phase, with each segment's band.

    Two columns (left arm, right arm), seven rows (s0..w2). The x axis is the task phase of
    :func:`task_phase`, so the sub-tasks of all demonstrations line up; each segment's
    [lower, upper] is a shaded band over the phases of its sub-tasks.

    Args:
        cs: the constraints (rad).
        demos: Baxter joint trajectories (rad) of the demonstrations.
        windows: demo name -> (2, 3, 2) sub-task windows, s (or objects with ``.windows``).
        path: output PNG.
        title: figure title (default: the set's name and segments).
    Returns:
        The written path.
    """
    fig = Figure(figsize=(10.5, 11.5), layout="constrained")
    axes = fig.subplots(_N_ARM, 2, sharex=True)
    colours = [f"C{i % 10}" for i in range(len(demos))]
    phases = []
    for d in demos:
        w = windows[d.name]
        phases.append(task_phase(d.time, getattr(w, "windows", w)))
    for c, arm in enumerate(ARMS):
        axes[0, c].set_title(f"{arm} arm", fontsize=11, color=ARM_COLOURS[arm], fontweight="bold")
        for j in range(_N_ARM):
            k = _N_ARM * c + j
            ax = axes[j, c]
            values = []
            for s, seg in enumerate(cs.segments):
                x0 = SUBTASKS.index(seg.subtasks[0])
                x1 = SUBTASKS.index(seg.subtasks[-1]) + 1
                lo, hi = np.rad2deg(seg.lower[k]), np.rad2deg(seg.upper[k])
                ax.fill_between([x0, x1], lo, hi, color=_SEGMENT_COLOURS[s % 3], alpha=0.18, lw=0,
                                label="+".join(seg.subtasks) if j == 0 else None)
                ax.hlines([lo, hi], x0, x1, color=_SEGMENT_COLOURS[s % 3], lw=1.0)
                values += [lo, hi]
            for d, ph, colour in zip(demos, phases, colours):
                y = np.rad2deg(d.q[:, k])
                ax.plot(ph[c], y, color=colour, lw=0.9)
                values.extend(y[np.isfinite(ph[c])].tolist())
            lo, hi = min(values), max(values)
            pad = max(0.08 * (hi - lo), 1.0)
            ax.set_ylim(lo - pad, hi + pad)
            for n in range(1, len(SUBTASKS)):
                ax.axvline(n, color="0.5", lw=0.6, ls=":")
            ax.set_ylabel(f"{BAXTER_JOINT_NAMES[j]} [deg]", fontsize=9)
            ax.grid(True, lw=0.3, alpha=0.5)
            ax.tick_params(labelsize=8)
        ax = axes[-1, c]
        ax.set_xlim(0, len(SUBTASKS))
        ax.set_xticks([n + 0.5 for n in range(len(SUBTASKS))], SUBTASKS)
        ax.set_xlabel("task phase (each sub-task rescaled to one unit)")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=9, frameon=False,
               title="constraint band of segment", title_fontsize=9)
    segs = ", ".join("+".join(s.subtasks) for s in cs.segments)
    fig.suptitle(title or f"Constraint set '{cs.name}' ({segs}) over {len(demos)} demonstrations", fontsize=12)
    return save_figure(fig, path)


def plot_volume_fractions(sets: Mapping[str, ConstraintSet], path: str | os.PathLike) -> Path:
    """How much of Baxter's joint range each segment leaves.

    Top: per joint, the width of each segment's range as a percentage of Baxter's range.
    Bottom: per segment and arm, the fraction of the arm's 7-D joint box (log scale).

    Args:
        sets: label -> constraint set (e.g. {"single": C1, "multi": C2/C3}).
        path: output PNG.
    """
    rows = [(label, s, seg) for label, cs in sets.items() for s, seg in enumerate(cs.segments)]
    widths = np.concatenate([cs.width_fractions() for cs in sets.values()])          # (R, 14)
    volumes = np.concatenate([arm_volume_fractions(cs) for cs in sets.values()])    # (R, 2)
    names = [f"{label}: {'+'.join(seg.subtasks)}" for label, _, seg in rows]
    fig = Figure(figsize=(12.0, 7.5), layout="constrained")
    top, bottom = fig.subplots(2, 1, height_ratios=[1.6, 1.0])
    n = len(rows)
    bar = 0.8 / n
    x = np.arange(len(JOINT_COLUMNS))
    for r in range(n):
        top.bar(x + (r - (n - 1) / 2) * bar, 100 * widths[r], bar, label=names[r], color=f"C{r}")
    top.set_xticks(x, [c.replace("_", "\n") for c in JOINT_COLUMNS], fontsize=8)
    top.set_ylabel("range width / Baxter's range [%]")
    top.axvline(_N_ARM - 0.5, color="0.4", lw=0.8)
    top.legend(fontsize=8, frameon=False)
    top.grid(True, axis="y", lw=0.3, alpha=0.6)
    top.set_title("Share of each joint's range left by each segment")
    xb = np.arange(n)
    for a, arm in enumerate(ARMS):
        bars = bottom.bar(xb + (a - 0.5) * 0.35, volumes[:, a], 0.35, label=f"{arm} arm", color=ARM_COLOURS[arm])
        bottom.bar_label(bars, labels=[f"{v:.1e}" for v in volumes[:, a]], fontsize=7, padding=1)
    bottom.set_yscale("log")
    bottom.set_xticks(xb, names, fontsize=8)
    bottom.set_ylabel("fraction of the arm's 7-D joint box")
    bottom.legend(fontsize=8, frameon=False)
    bottom.grid(True, axis="y", lw=0.3, alpha=0.6)
    bottom.set_title("Volume fraction (product of the seven widths)")
    return save_figure(fig, path)


def plot_expert_inside(fractions: Mapping[str, tuple[ConstraintSet, np.ndarray]], path: str | os.PathLike, *,
                       subtitle: str = "") -> Path:
    """Heat map: share of the expert's steps inside each segment's range, per joint.

    Args:
        fractions: label -> (constraint set, (S, 14) fraction inside in [0, 1], NaN for none).
        path: output PNG.
        subtitle: appended to the title (e.g. the number of episodes).
    """
    names, rows = [], []
    for label, (cs, frac) in fractions.items():
        for s, seg in enumerate(cs.segments):
            names.append(f"{label}: {'+'.join(seg.subtasks)}")
            rows.append(frac[s])
    data = 100 * np.array(rows)
    fig = Figure(figsize=(13.0, 1.0 + 0.55 * len(rows) + 1.2), layout="constrained")
    ax = fig.subplots()
    image = ax.imshow(data, cmap="RdYlGn", vmin=0, vmax=100, aspect="auto")
    for (r, k), v in np.ndenumerate(data):
        ax.text(k, r, "-" if np.isnan(v) else f"{v:.0f}", ha="center", va="center", fontsize=8)
    ax.set_xticks(np.arange(len(JOINT_COLUMNS)), [c.replace("_", "\n") for c in JOINT_COLUMNS], fontsize=8)
    ax.set_yticks(np.arange(len(names)), names, fontsize=8)
    ax.axvline(_N_ARM - 0.5, color="k", lw=1.0)
    fig.colorbar(image, ax=ax, label="steps inside [%]", shrink=0.9)
    ax.set_title("Scripted expert: share of steps with the joint inside the range of its arm's current segment"
                 + (f" ({subtitle})" if subtitle else ""), fontsize=10)
    return save_figure(fig, path)
