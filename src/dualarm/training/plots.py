"""Learning curves of a run directory: training return and success, evaluation success."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from dualarm.atomic import atomic_path
from dualarm.training.run_dir import RunPaths


def _read(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return {}
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def moving_average(x: np.ndarray, window: int) -> np.ndarray:
    """Trailing mean over up to ``window`` values (shorter at the start), same length as x."""
    from dualarm.curves import trailing_mean

    return trailing_mean(x, window)[0]


def plot_run(run_dir: str | Path, output: str | Path, window: int = 100) -> Path:
    """Write a PNG with the return (moving average), the success rate (moving average and
    evaluations) against episodes, and wall time on a second axis of the success panel.

    Returns the output path.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = RunPaths(run_dir)
    m = _read(paths.metrics)
    e = _read(paths.eval) if paths.eval.exists() else {}
    fig, (ax_r, ax_s) = plt.subplots(1, 2, figsize=(11, 4))
    if m:
        ep = m["episode"]
        ax_r.plot(ep, m["return_total"], color="0.8", lw=0.5, label="episode")
        ax_r.plot(ep, moving_average(m["return_total"], window), color="C0",
                  label=f"mean of last {window}")
        ax_s.plot(ep, moving_average(m["success"], window), color="C0",
                  label=f"training (last {window}, with noise)")
    if e:
        ax_s.plot(e["episode"], e["success_rate"], "o-", color="C3", ms=3,
                  label="evaluation (no noise)")
    ax_r.set(xlabel="episode", ylabel="return, both arms", title="Return")
    ax_s.set(xlabel="episode", ylabel="success rate", ylim=(-0.02, 1.02), title="Success")
    if m and len(m["episode"]) < 2:     # one episode: give the axes a width to draw in
        for ax in (ax_r, ax_s):
            ax.set_xlim(m["episode"][0] - 1, m["episode"][0] + 1)
    ax_r.legend(loc="lower right")
    ax_s.legend(loc="upper left")
    if m and np.ptp(m["wall_time_s"]) > 0:   # the wall-time axis needs time to pass
        top = ax_s.secondary_xaxis("top", functions=(
            lambda x: np.interp(x, m["episode"], m["wall_time_s"]) / 60,
            lambda t: np.interp(t * 60, m["wall_time_s"], m["episode"])))
        top.set_xlabel("wall time, min")
    fig.suptitle(str(paths.root.name))
    fig.tight_layout()
    output = Path(output)
    with atomic_path(output) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return output
