"""A comparison summarised per condition over its seeds, next to the paper's values: episodes
to target success, convergence, maximum average success, their 95% intervals and the ratios
between conditions (``build_report``). The definitions are in ``dualarm.curves``
and docs/report.md."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dualarm.errors import InputError
from dualarm.task import COMPARED_CONDITIONS, TARGET_SUCCESS
from dualarm.curves import (RATIO_PAIRS, Convergence, condition_ratios, convergence,
                                         episodes_to_target, max_average, mean_ci,
                                         median_ratio_ci, trailing_mean)
from dualarm.experiments.run_logs import EVAL_SUCCESS_COLUMNS, Run, find_run_dirs, load_run


#: The quantities whose ratios between conditions the report gives (the paper quotes all but
#: the time to the target).
RATIO_QUANTITIES = ("episodes_to_target", "time_to_target_s", "convergence_episode",
                    "convergence_time_s")

#: The paper's values (Section 3.2.2, Figs. 6-8; 10,000 training episodes per condition).
PAPER = {
    "episodes_to_target": {"multi": 4480, "single": 5810, "none": 7685},   # success >= 0.85
    "convergence_episode": {"multi": 4000, "single": 5600, "none": 7000},
    "convergence_time_s": {"multi": 48590, "single": 75830, "none": 96393},
    "max_avg_success": {"multi": 0.98, "single": 0.94, "none": 0.98},
}

#: Ratios the text quotes; the others shown are derived from the values in ``PAPER``.
PAPER_QUOTED_RATIOS = {
    ("episodes_to_target", ("multi", "single")): 0.77,
    ("episodes_to_target", ("multi", "none")): 0.58,
    ("convergence_episode", ("multi", "single")): 0.71,
    ("convergence_episode", ("multi", "none")): 0.57,
    ("convergence_episode", ("single", "none")): 0.80,
    ("convergence_time_s", ("multi", "single")): 0.64,
    ("convergence_time_s", ("multi", "none")): 0.50,
}

QUANTITY_NAMES = {
    "episodes_to_target": "episodes to target success",
    "time_to_target_s": "time to target success",
    "convergence_episode": "episodes to convergence",
    "convergence_time_s": "time to convergence",
    "max_avg_success": "max average success",
    "final_eval_success": "final evaluation success",
}


@dataclass(frozen=True, eq=False)
class SeedStat:
    """A per-seed quantity summarised over the seeds of a condition.

    Attributes:
        values: (seeds,) one value per seed, NaN where that seed did not reach the criterion.
        mean: mean over the seeds that reached it (NaN if none did).
        ci95: half-width of the 95% Student-t interval of that mean (NaN with < 2 values).
        reached: number of seeds with a value.
    """

    values: np.ndarray
    mean: float
    ci95: float
    reached: int

    @classmethod
    def of(cls, values) -> "SeedStat":
        v = np.asarray([math.nan if x is None else x for x in values], dtype=float)
        ok = v[np.isfinite(v)]
        mean, half = mean_ci(ok)
        return cls(v, mean, half, len(ok))

    @property
    def seeds(self) -> int:
        return len(self.values)

    @property
    def partial(self) -> bool:
        """Some seeds, but not all, reached the criterion."""
        return 0 < self.reached < self.seeds


@dataclass(frozen=True, eq=False)
class ConditionSummary:
    """One condition over its seeds, on the episodes common to all its runs.

    Attributes:
        condition: "none", "single" or "multi".
        runs: its runs, by seed.
        episodes: common episode range 1..episodes (the shortest run's length).
        ma_return: (seeds, episodes) moving average of the return, per seed.
        ma_success: (seeds, episodes) moving average of the success, per seed.
        convergence: per seed, the convergence of its return curve.
        episodes_to_target, time_to_target_s (s), convergence_episode, convergence_time_s
        (s), max_avg_success, final_eval_success: per-seed quantities (see docs/report.md).
        eval_episode: (k,) evaluation episodes common to all runs, within the common range.
        eval_success: (seeds, k) evaluation success rates at those episodes.
    """

    condition: str
    runs: list[Run]
    episodes: int
    ma_return: np.ndarray
    ma_success: np.ndarray
    convergence: list[Convergence]
    episodes_to_target: SeedStat
    time_to_target_s: SeedStat
    convergence_episode: SeedStat
    convergence_time_s: SeedStat
    max_avg_success: SeedStat
    final_eval_success: SeedStat
    eval_episode: np.ndarray
    eval_success: np.ndarray

    @property
    def seeds(self) -> int:
        return len(self.runs)

    @property
    def truncated(self) -> bool:
        """True when some of its runs are longer than the common range."""
        return any(r.episodes > self.episodes for r in self.runs)

    def stat(self, quantity: str) -> SeedStat:
        return getattr(self, quantity)


def measured_on_evals(runs: list[Run]) -> bool:
    """Whether a condition's episodes to target and max success are read from its runs'
    evaluations: one run that needs it (``Run.measured_on_evals``) decides for all, so that a
    condition's seeds are measured alike."""
    return any(r.measured_on_evals for r in runs)


@dataclass
class Report:
    """Everything the report shows.

    Attributes:
        source: the comparison directory.
        window: moving-average window, episodes.
        target: success target of "episodes to target".
        runs: every run read, sorted by condition and seed.
        conditions: condition -> summary, in ``COMPARED_CONDITIONS`` (absent conditions left out).
        ratios: quantity (``RATIO_QUANTITIES``) -> (numerator, denominator) -> ratio of the
            per-condition means, or None when not available.
        median_ratios: the same keys -> (ratio, low, high) of the per-condition medians with
            unreached seeds counted as beyond the run, and its 95% seed-bootstrap interval
            (``metrics.median_ratio_ci``), or None when not available.
        notes: remarks a reader must see (partial runs, truncation, flagged means).
        actors: whose evaluations were read: "policy" (eval.csv ``success_rate``) or
            "average" (``average_success_rate``, the averaged actors evaluated beside).
        human: condition -> each measured run's ``HumanLikeness`` (``human_likeness``).
        human_reference: the demonstrations' posture distance among themselves, rad.
    """

    source: Path
    window: int
    target: float
    runs: list[Run]
    conditions: dict[str, ConditionSummary]
    ratios: dict[str, dict[tuple[str, str], float | None]]
    median_ratios: dict[str, dict[tuple[str, str], tuple[float, float, float] | None]]
    notes: list[str] = field(default_factory=list)
    actors: str = "policy"
    human: dict = field(default_factory=dict)
    human_reference: float | None = None


def summarize_condition(condition: str, runs: list[Run], window: int = 100,
                        target: float = TARGET_SUCCESS) -> ConditionSummary:
    """Per-seed curves and quantities of one condition, on the episodes common to its runs.

    Args:
        condition: the condition of every run in ``runs``.
        runs: at least one run, each with at least one episode.
        window: moving-average window, episodes.
        target: success rate of "episodes to target".
    """
    n = min(r.episodes for r in runs)       # the curves' common range
    # Each run's quantities are read up to the runs still going's common range, or, for a run
    # that ended by reaching its stop_at, to its own end (its later episodes were not needed).
    going = [r.episodes for r in runs if not r.stopped]
    upto = [r.episodes if r.stopped or not going else min(going) for r in runs]
    # Training success from later starts is not the task's, and a run that stops at an
    # evaluation ends before its training success can show it: measure those on evaluations.
    on_evals = measured_on_evals(runs)
    ma_return = np.stack([trailing_mean(r.return_total[:n], window)[0] for r in runs])
    ma_success = np.stack([trailing_mean(r.success[:n], window)[0] for r in runs])
    conv = [convergence(r.return_total[:h], window) for r, h in zip(runs, upto)]
    conv_time = [r.wall_time_s[c.episode - 1] if c.converged else None for r, c in zip(runs, conv)]
    final_eval = []
    for r, h in zip(runs, upto):
        inside = r.eval_episode <= h
        final_eval.append(r.eval_success[inside][-1] if inside.any() else None)
    common = sorted(set.intersection(*(set(r.eval_episode[r.eval_episode <= n].tolist())
                                       for r in runs)))
    eval_success = np.array([[r.eval_success[r.eval_episode == ep][-1] for ep in common]
                             for r in runs]).reshape(len(runs), len(common))
    to_target = [_first_evaluation_at(r, h, target) if on_evals
                 else episodes_to_target(r.success[:h], target, window) for r, h in zip(runs, upto)]
    return ConditionSummary(
        condition=condition, runs=runs, episodes=n, ma_return=ma_return, ma_success=ma_success,
        convergence=conv,
        episodes_to_target=SeedStat.of(to_target),
        time_to_target_s=SeedStat.of([None if e is None else float(r.wall_time_s[e - 1])
                                      for r, e in zip(runs, to_target)]),
        convergence_episode=SeedStat.of([c.episode for c in conv]),
        convergence_time_s=SeedStat.of(conv_time),
        max_avg_success=SeedStat.of([float(np.max(r.eval_success[r.eval_episode <= h], initial=0.0))
                                     if on_evals else max_average(r.success[:h], window)
                                     for r, h in zip(runs, upto)]),
        final_eval_success=SeedStat.of(final_eval),
        eval_episode=np.array(common, dtype=int), eval_success=eval_success)


def _first_evaluation_at(run: Run, n: int, target: float) -> int | None:
    """The first evaluation episode (<= n) whose success is at least ``target``, or None."""
    hit = (run.eval_episode <= n) & (run.eval_success >= target)
    return int(run.eval_episode[hit][0]) if hit.any() else None


def build_report(comparison_dir: str | Path, window: int = 100, target: float = TARGET_SUCCESS,
                 actors: str = "policy") -> Report:
    """Read every run under ``comparison_dir`` and summarise each condition.

    Args:
        comparison_dir: a directory whose run directories (``config.yaml`` + ``metrics.csv``)
            lie at most two levels below it (``dualarm compare`` writes ``DIR/runs/<name>/``).
        window: moving-average window, episodes, >= 1.
        target: success rate of "episodes to target", in (0, 1].
        actors: the evaluations read (``load_run``): "policy", each run's own policy, or
            "average", the averaged actors its evaluations ran beside it.

    Raises:
        InputError: no run directory, or a bad run directory (see ``load_run``).
    """
    root = Path(comparison_dir)
    if int(window) != window or window < 1:
        raise InputError(f"window must be a whole number of episodes >= 1, got {window!r}")
    if not 0 < target <= 1:
        raise InputError(f"target must be a success rate in (0, 1], got {target!r}")
    if not root.is_dir():
        raise InputError("not a directory", source=str(root))
    dirs = find_run_dirs(root)
    if not dirs:
        raise InputError("no run directories (directories with config.yaml and metrics.csv) "
                         "here or up to two levels below", source=str(root))
    runs = sorted((load_run(d, actors) for d in dirs),
                  key=lambda r: (COMPARED_CONDITIONS.index(r.condition), r.seed, str(r.path)))
    notes = []
    if actors == "average":
        notes.append(f"evaluations are the averaged actors' (eval.csv "
                     f"{EVAL_SUCCESS_COLUMNS['average']}), evaluated beside each run's own "
                     "policy on the same placements")
    for r in runs:
        where = relative_to_root(r.path, root)
        notes += [f"{where}: {n}" for n in r.notes]
        if r.partial:
            notes.append(f"{where}: partial run, {r.episodes} of {r.planned_episodes} planned "
                         "episodes (still running or stopped)")
    seen: dict[tuple[str, int], Path] = {}
    for r in runs:
        key = (r.condition, r.seed)
        if key in seen:
            notes.append(f"{relative_to_root(r.path, root)} and {relative_to_root(seen[key], root)} are both "
                         f"{r.condition} seed {r.seed}; both are counted")
        seen.setdefault(key, r.path)
    empty = [r for r in runs if r.episodes == 0]
    notes += [f"{relative_to_root(r.path, root)}: no episodes logged yet; left out" for r in empty]
    runs_used = [r for r in runs if r.episodes > 0]
    if not runs_used:
        raise InputError("none of its runs has logged an episode yet", source=str(root))
    conditions = {}
    for c in COMPARED_CONDITIONS:
        group = [r for r in runs_used if r.condition == c]
        if group:
            conditions[c] = summarize_condition(c, group, int(window), float(target))
    for s in conditions.values():
        if s.truncated:
            notes.append(f"{s.condition}: runs of {min(r.episodes for r in s.runs)}-"
                         f"{max(r.episodes for r in s.runs)} episodes; compared over their "
                         f"common range, episodes 1-{s.episodes}")
        if s.episodes < window:
            notes.append(f"{s.condition}: {s.episodes} episodes, fewer than the {window}-episode "
                         "window: no full-window average yet")
    on_evals = {c: s for c, s in conditions.items() if measured_on_evals(s.runs)}
    if on_evals:
        why = {c: "training episodes start at later sub-tasks too (starts.probs)"
               if any(r.later_starts for r in s.runs) else
               "its runs end at the evaluation that reaches their stop_at"
               for c, s in on_evals.items()}
        notes.append("; ".join(f"{c}: {w}" for c, w in why.items())
                     + ": so episodes to target success and max success are read from the "
                     "evaluations (deterministic policy, normal reset), not from training "
                     "success; convergence still reads training returns")
    stopped = [r for r in runs if r.stopped]
    if stopped:
        notes.append("runs that reached their stop_at ended at that evaluation ("
                     + ", ".join(f"{r.condition} seed {r.seed} at {r.episodes}" for r in stopped)
                     + "): their curves end there")
    going = {c: s for c, s in conditions.items() if not all(r.stopped for r in s.runs)}
    if len({s.episodes for s in going.values()}) > 1:
        notes.append("the conditions cover different episode ranges ("
                     + ", ".join(f"{c} {s.episodes}" for c, s in going.items())
                     + "): a condition cannot reach a criterion beyond its own range")
    ratios = {q: condition_ratios({c: (s.stat(q).mean if s.stat(q).reached else None)
                                   for c, s in conditions.items()})
              for q in RATIO_QUANTITIES}
    median_ratios = {q: {(a, b): median_ratio_ci(conditions[a].stat(q).values,
                                                 conditions[b].stat(q).values)
                         if a in conditions and b in conditions else None
                         for a, b in RATIO_PAIRS}
                     for q in RATIO_QUANTITIES}
    for s in conditions.values():
        for q in ("episodes_to_target", "convergence_episode"):
            st = s.stat(q)
            if st.partial:
                notes.append(f"{s.condition}: only {st.reached} of {st.seeds} seeds reached "
                             f"{'the target' if q == 'episodes_to_target' else 'convergence'}; "
                             "its mean and ratios are over those seeds (marked †)")
    return Report(source=root, window=int(window), target=float(target), runs=runs,
                  conditions=conditions, ratios=ratios, median_ratios=median_ratios, notes=notes,
                  actors=actors)


def relative_to_root(path: Path, root: Path) -> str:
    try:
        rel = path.relative_to(root)
        return str(rel) if str(rel) != "." else path.name
    except ValueError:
        return str(path)


def paper_ratio(quantity: str, pair: tuple[str, str]) -> tuple[float, bool]:
    """The paper's ratio of ``quantity`` for ``pair`` and whether its text quotes it (else it
    is derived from the paper's per-condition values); (None, False) where the paper gives
    neither."""
    quoted = PAPER_QUOTED_RATIOS.get((quantity, pair))
    if quoted is not None:
        return quoted, True
    values = PAPER.get(quantity, {})
    if pair[0] not in values or pair[1] not in values:
        return None, False
    return values[pair[0]] / values[pair[1]], False


def paper_value(report: Report, quantity: str, condition: str) -> float | None:
    if quantity == "episodes_to_target" and not math.isclose(report.target, TARGET_SUCCESS):
        return None
    return PAPER.get(quantity, {}).get(condition)


def ratio_note(report: Report, quantity: str, pair: tuple[str, str]) -> str:
    """Why a ratio is missing, or which of its means cover only some seeds ("" if neither)."""
    parts = []
    for c in pair:
        s = report.conditions.get(c)
        if s is None:
            parts.append(f"no {c} runs")
        elif s.stat(quantity).reached == 0:
            parts.append(f"no {c} seed reached it")
        elif s.stat(quantity).partial:
            parts.append(f"{c}: {s.stat(quantity).reached}/{s.seeds} seeds")
    return "; ".join(parts)
