"""Draw docs/figures/human_demos_summary.png: episodes to 0.85 evaluation success, run by run,
for the conditions of this page, from the run logs in runs/ (each run's config.yaml and
eval.csv); a run that never reached 0.85 is drawn at its budget, hollow (censored).

    python docs/human-demos/plot_summary.py          # from the repository root
"""

from __future__ import annotations

import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import yaml  # noqa: E402

from dualarm.curves import median_ratio_ci  # noqa: E402

HERE = Path(__file__).resolve().parent
RUNS = HERE / "runs"
OUT = HERE.parent / "figures" / "human_demos_summary.png"
TARGET = 0.85

#: (label, run-log prefix, seeds), top to bottom; None between the two settings.
ROWS = (
    ("the recipe alone", "recipe-ups1-s", range(10)),
    ("+ the 10 recordings (moved, 256)", "ups1-s", range(10)),
    ("+ 3 recordings", "ups1-count3-s", range(5)),
    ("+ 1 recording", "ups1-count1-s", range(5)),
    ("+ the recordings, shuffled in time", "ups1-shuffled-s", range(5)),
    ("+ a scripted expert's 256 episodes", "expert-s", range(5)),
    None,
    ("the recipe alone", "nocur-recipe-s", range(10)),
    ("+ the recordings", "nocur-demos-s", range(10)),
    ("+ the recordings, their states as starts", "dstart-s", range(10)),
    ("the recordings' states as starts alone", "sonly-s", range(10)),
)


def first_crossing(run: Path) -> tuple[float, bool]:
    """(episodes, reached): the first evaluation at ``TARGET`` or above, else the budget."""
    with open(run / "eval.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    episodes = np.array([float(r["episode"]) for r in rows])
    success = np.array([float(r["success_rate"]) for r in rows])
    hit = np.flatnonzero(success >= TARGET)
    if hit.size:
        return float(episodes[hit[0]]), True
    budget = yaml.safe_load((run / "config.yaml").read_text())["episodes"]
    return float(budget), False


def main() -> None:
    fig, ax = plt.subplots(figsize=(8.5, 5.2))
    labels, y = [], 0
    medians = {}
    for row in ROWS:
        if row is None:
            ax.axhline(y - 0.5, color="0.6", lw=0.8)
            y += 0.6
            continue
        label, prefix, seeds = row
        points = [first_crossing(RUNS / f"{prefix}{s}") for s in seeds]
        x = np.array([p[0] for p in points])
        reached = np.array([p[1] for p in points])
        jitter = np.linspace(-0.18, 0.18, len(x))
        ax.scatter(x[reached], y + jitter[reached], s=22, color="C0", zorder=3)
        ax.scatter(x[~reached], y + jitter[~reached], s=22, facecolors="none",
                   edgecolors="C3", zorder=3)
        med = float(np.median(x))
        medians[prefix] = np.where(reached, x, np.nan)
        ax.plot([med, med], [y - 0.3, y + 0.3], color="k", lw=2)
        bound = "at least " if (~reached).sum() * 2 >= len(x) else ""
        ax.text(2130, y, f"{bound}{med:,.0f}  ({reached.sum()}/{len(x)})", va="center", fontsize=8)
        labels.append((y, label))
        y += 1
    ax.set_yticks([p for p, _ in labels], [t for _, t in labels], fontsize=8)
    ax.set_ylim(y - 0.4, -1.1)          # top to bottom, room for the settings' names
    ax.set_xlim(0, 2750)
    ax.set_xlabel("training episodes to 0.85 evaluation success (condition multi, evaluations every 80)")
    ax.text(20, -0.7, "with the simulator's placed starts (the recipe's reverse curriculum)",
            fontsize=8, color="0.3", style="italic")
    ax.text(20, 6.4, "from the robot's reset only (configs/reset-starts.yaml)", fontsize=8,
            color="0.3", style="italic")
    ax.text(2130, -0.7, "median (reached)", fontsize=8, color="0.3")
    ratio, lo, hi = median_ratio_ci(medians["recipe-ups1-s"], medians["ups1-s"])
    ax.set_title(f"Human recordings under the recipe: placed starts, recipe / recordings "
                 f"{ratio:.2f} ({lo:.2f}-{hi:.2f})\nhollow: never reached 0.85, drawn at the "
                 "run's budget", fontsize=9)
    fig.tight_layout()
    fig.savefig(OUT, dpi=130)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
