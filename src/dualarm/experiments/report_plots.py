"""Figures of the comparison report: Fig. 6 (return), Fig. 7 (success), Fig. 8 (time to
convergence), one colour per condition throughout."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dualarm.atomic import atomic_path
from dualarm.curves import mean_ci

if TYPE_CHECKING:
    from dualarm.experiments.summary import ConditionSummary, Report

#: One colour per condition, the same in every figure.
COLOURS = {"none": "#1f77b4", "single": "#ff7f0e", "multi": "#2ca02c", "demos": "#d62728"}


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _label(s: "ConditionSummary") -> str:
    from dualarm.task import CONDITION_NAMES

    seeds = (f"{s.seeds} seeds, 95% CI" if s.seeds > 1 else "1 seed, no CI")
    return f"{CONDITION_NAMES[s.condition]} ({seeds})"


def _band(ax, x: np.ndarray, curves: np.ndarray, colour: str, label: str) -> None:
    """Mean over seeds of ``curves`` (seeds, len(x)), with its 95% t-interval when seeds > 1."""
    mean, half = mean_ci(curves, axis=0)
    ax.plot(x, mean, color=colour, lw=1.5, label=label)
    if curves.shape[0] > 1:
        ax.fill_between(x, mean - half, mean + half, color=colour, alpha=0.2, lw=0)


def _footnote(fig, report: "Report", extra: tuple[str, ...] = ()) -> float:
    """Write the figure's remarks at its bottom; returns the height they take (figure units)."""
    lines = list(extra)
    if any(s.truncated for s in report.conditions.values()):
        lines.append("Runs of a condition with different lengths: shown over their common "
                     "episode range.")
    if any(r.partial for r in report.runs):
        lines.append("Some runs are partial (fewer episodes than planned); see the notes.")
    if lines:
        fig.text(0.01, 0.005, "\n".join(lines), fontsize=8, color="0.3", va="bottom")
    return 0.01 + 0.035 * len(lines)


def _save(fig, path: Path) -> Path:
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110)
    _plt().close(fig)
    return path


def plot_return(report: "Report", path: str | Path) -> Path:
    """Fig. 6: moving-average return per condition (mean over seeds, 95% CI band) against
    training episodes; dotted lines at each condition's mean convergence episode."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 4.6))
    for c, s in report.conditions.items():
        x = np.arange(1, s.episodes + 1)
        _band(ax, x, s.ma_return, COLOURS[c], _label(s))
        if s.convergence_episode.reached:
            ax.axvline(s.convergence_episode.mean, color=COLOURS[c], ls=":", lw=1.2)
    ax.plot([], [], color="0.4", ls=":", label="mean convergence episode")
    ax.set(xlabel="training episode", ylabel=f"return, both arms (mean of last {report.window})",
           title="Fig. 6: average cumulative return")
    lo = min(s.ma_return.min() for s in report.conditions.values())
    hi = max(s.ma_return.max() for s in report.conditions.values())
    pad = 0.05 * (hi - lo) or 1.0
    ax.set_ylim(lo - pad, hi + pad)               # bands of few seeds may reach beyond the data
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(alpha=0.3)
    bottom = _footnote(fig, report, ("Bands: 95% CI of the mean over seeds (Student t), "
                                     "clipped to the range of the per-seed curves.",))
    fig.tight_layout(rect=(0, bottom, 1, 1))
    return _save(fig, path)


def plot_success(report: "Report", path: str | Path) -> Path:
    """Fig. 7: moving-average training success per condition (mean over seeds, 95% CI band),
    with the target line and each condition's mean episode to reach it; second panel: the
    deterministic evaluations of eval.csv (mean over seeds, 95% CI)."""
    plt = _plt()
    fig, (ax, ax_e) = plt.subplots(1, 2, figsize=(12, 4.6), sharey=True)
    for c, s in report.conditions.items():
        x = np.arange(1, s.episodes + 1)
        _band(ax, x, s.ma_success, COLOURS[c], _label(s))
        if s.episodes_to_target.reached:
            ax.axvline(s.episodes_to_target.mean, color=COLOURS[c], ls=":", lw=1.2)
        if len(s.eval_episode):
            mean, half = mean_ci(s.eval_success, axis=0)
            ax_e.plot(s.eval_episode, mean, "o-", color=COLOURS[c], ms=3, lw=1, label=_label(s))
            if s.seeds > 1:
                ax_e.fill_between(s.eval_episode, mean - half, mean + half, color=COLOURS[c],
                                  alpha=0.2, lw=0)
    for a in (ax, ax_e):
        a.axhline(report.target, color="k", ls="--", lw=0.8)
        a.grid(alpha=0.3)
    ax.plot([], [], color="k", ls="--", lw=0.8, label=f"target {report.target:g}")
    ax.plot([], [], color="0.4", ls=":", label=f"mean episode to reach {report.target:g}")
    ax.set(xlabel="training episode", ylabel="success rate", ylim=(-0.02, 1.02),
           title=f"Fig. 7: average success rate (training, last {report.window})")
    ax_e.set(xlabel="training episode", title="evaluation (deterministic policy, eval.csv)")
    ax.legend(loc="lower right", fontsize=8)
    if any(len(s.eval_episode) for s in report.conditions.values()):
        ax_e.legend(loc="upper left", fontsize=8)
    else:
        ax_e.text(0.5, 0.5, "no evaluations common to the runs", ha="center",
                  transform=ax_e.transAxes, color="0.4")
    bottom = _footnote(fig, report)
    fig.tight_layout(rect=(0, bottom, 1, 1))
    return _save(fig, path)


def _time_unit(seconds: float) -> tuple[float, str]:
    if seconds >= 3 * 3600:
        return 3600.0, "h"
    if seconds >= 180:
        return 60.0, "min"
    return 1.0, "s"


def plot_convergence_time(report: "Report", path: str | Path) -> Path:
    """Fig. 8: training wall time (left) and episodes (right) to convergence of the return
    curve per condition: bar = mean over the converged seeds, error bar = 95% CI, filled dots
    = converged seeds, open triangles = seeds that did not converge, drawn at the end of their
    compared range (a lower bound)."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(11, 5))
    conds = list(report.conditions)
    ends_t = [s.runs[k].wall_time_s[s.episodes - 1] for s in report.conditions.values()
              for k in range(s.seeds)]
    scale, unit = _time_unit(max(ends_t, default=0.0))
    rng = np.random.default_rng(0)
    panels = [(axes[0], "convergence_time_s", scale, f"training time to convergence, {unit}"),
              (axes[1], "convergence_episode", 1.0, "episodes to convergence")]
    for ax, quantity, div, ylabel in panels:
        for i, c in enumerate(conds):
            s = report.conditions[c]
            st = s.stat(quantity)
            col = COLOURS[c]
            if st.reached:
                err = st.ci95 / div if np.isfinite(st.ci95) else None
                ax.bar(i, st.mean / div, 0.6, color=col, alpha=0.45, edgecolor=col,
                       yerr=err, capsize=6)
            jitter = rng.uniform(-0.15, 0.15, s.seeds)
            for k, v in enumerate(st.values):
                if np.isfinite(v):
                    ax.plot(i + jitter[k], v / div, "o", color=col, mec="k", mew=0.5, ms=6)
                else:
                    end = (s.runs[k].wall_time_s[s.episodes - 1] if quantity == "convergence_time_s"
                           else s.episodes)
                    ax.plot(i + jitter[k], end / div, "^", mfc="none", mec=col, mew=1.5, ms=8)
            ax.annotate(f"{st.reached}/{st.seeds} converged", (i, 0), xytext=(0, -30),
                        textcoords="offset points", ha="center", fontsize=8, color="0.3",
                        annotation_clip=False)
        ax.set_xticks(range(len(conds)), [c for c in conds])
        ax.set(ylabel=ylabel, xlim=(-0.6, len(conds) - 0.4))
        ax.set_ylim(bottom=0)
        ax.grid(axis="y", alpha=0.3)
    handles = [
        axes[0].plot([], [], "s", color="0.5", alpha=0.45, ms=9,
                     label="mean of the converged seeds, 95% CI")[0],
        axes[0].plot([], [], "o", color="0.5", mec="k", mew=0.5, label="one converged seed")[0],
        axes[0].plot([], [], "^", mfc="none", mec="0.3", mew=1.5,
                     label="not converged (drawn at the end of its compared range)")[0]]
    fig.suptitle("Fig. 8: training time to convergence of the average return curve")
    fig.legend(handles=handles, loc="upper center", ncol=3, fontsize=8, frameon=False,
               bbox_to_anchor=(0.5, 0.94))
    bottom = _footnote(fig, report)
    fig.tight_layout(rect=(0, bottom, 1, 0.9))
    return _save(fig, path)
