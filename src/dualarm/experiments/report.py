"""`dualarm report`: the run directories of a comparison -> Figs. 6-8, a table and an HTML page.

``build_report`` reads every run directory under a comparison directory and summarises each
condition over its seeds; ``write_report`` writes the figures, ``table.md``, ``table.csv`` and
``index.html``. The definitions (moving average, episodes to target, convergence, confidence
interval) are in ``dualarm.experiments.metrics`` and docs/report.md.
"""

from __future__ import annotations

import csv
import html
import io
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dualarm.atomic import atomic_open
from dualarm.errors import InputError
from dualarm.task import CONDITION_NAMES, CONDITIONS, TARGET_SUCCESS
from dualarm.experiments.metrics import (RATIO_PAIRS, Convergence, condition_ratios, convergence,
                                         episodes_to_target, max_average, mean_ci, trailing_mean)

#: Columns a run's metrics.csv must have (the others are not read).
METRICS_READ = ("episode", "wall_time_s", "return_total", "success")
#: Columns an eval.csv must have when it has rows.
EVAL_READ = ("episode", "success_rate")
#: The quantities whose ratios between conditions the paper quotes.
RATIO_QUANTITIES = ("episodes_to_target", "convergence_episode", "convergence_time_s")

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
    "convergence_episode": "episodes to convergence",
    "convergence_time_s": "time to convergence",
    "max_avg_success": "max average success",
    "final_eval_success": "final evaluation success",
}


@dataclass(frozen=True, eq=False)
class Run:
    """The curves of one training run directory.

    Attributes:
        path: the run directory.
        condition: "none", "single" or "multi" (from config.yaml).
        seed: the run's seed.
        planned_episodes: ``episodes`` of its config (the run is partial if it has fewer).
        wall_time_s: (n,) cumulative training time at the end of each episode, s.
        return_total: (n,) return of each training episode, both arms.
        success: (n,) 1 if the training episode succeeded, else 0.
        eval_episode: (k,) training episodes after which an evaluation ran.
        eval_success: (k,) success rate of each evaluation, in [0, 1].
        notes: remarks on reading it (e.g. an incomplete last row dropped).
    """

    path: Path
    condition: str
    seed: int
    planned_episodes: int
    wall_time_s: np.ndarray
    return_total: np.ndarray
    success: np.ndarray
    eval_episode: np.ndarray
    eval_success: np.ndarray
    notes: tuple[str, ...] = ()

    @property
    def episodes(self) -> int:
        """Training episodes logged in metrics.csv."""
        return len(self.success)

    @property
    def partial(self) -> bool:
        """True when the run logged fewer episodes than its config asks for."""
        return self.episodes < self.planned_episodes


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
        episodes_to_target, convergence_episode, convergence_time_s (s), max_avg_success,
        final_eval_success: per-seed quantities (see docs/report.md).
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


@dataclass
class Report:
    """Everything the report shows.

    Attributes:
        source: the comparison directory.
        window: moving-average window, episodes.
        target: success target of "episodes to target".
        runs: every run read, sorted by condition and seed.
        conditions: condition -> summary, in ``CONDITIONS`` (absent conditions left out).
        ratios: quantity (``RATIO_QUANTITIES``) -> (numerator, denominator) -> ratio of the
            per-condition means, or None when not available.
        notes: remarks a reader must see (partial runs, truncation, flagged means).
    """

    source: Path
    window: int
    target: float
    runs: list[Run]
    conditions: dict[str, ConditionSummary]
    ratios: dict[str, dict[tuple[str, str], float | None]]
    notes: list[str] = field(default_factory=list)


# ----------------------------------------------------------------------------- reading

def find_run_dirs(comparison_dir: str | Path, depth: int = 2) -> list[Path]:
    """Directories holding ``config.yaml`` and ``metrics.csv``: ``comparison_dir`` itself and
    those up to ``depth`` levels below it (hidden ones skipped), sorted by path."""
    from dualarm.training.run_dir import RunPaths

    root = Path(comparison_dir)
    found, level = [], [root]
    for d in range(depth + 1):
        found += [p for p in level if RunPaths(p).config.is_file() and RunPaths(p).metrics.is_file()]
        if d < depth:
            level = [c for p in level for c in sorted(p.iterdir())
                     if c.is_dir() and not c.name.startswith(".")]
    return sorted(found)


def _read_columns(path: Path, required: tuple[str, ...]) -> tuple[dict[str, np.ndarray], list[str]]:
    """Columns ``required`` of a CSV file as float arrays (finite values only).

    A last row with too few fields and no line end is a row being written: it is dropped,
    with a note. Any other bad row raises ``InputError`` naming the file, row and column.
    """
    try:
        text = path.read_text()
    except OSError as exc:
        raise InputError(f"cannot read ({exc.strerror})", source=str(path)) from None
    rows = [r for r in csv.reader(io.StringIO(text)) if r]
    if not rows:
        raise InputError("empty file, no header", source=str(path))
    header, data = [h.strip() for h in rows[0]], rows[1:]
    for name in required:
        if name not in header:
            raise InputError(f"missing required column (the file has: {', '.join(header)})",
                             source=str(path), column=name)
    notes = []
    if data and len(data[-1]) < len(header) and not text.endswith("\n"):
        data = data[:-1]
        notes.append(f"{path.name}: dropped an incomplete last row (still being written)")
    for i, row in enumerate(data, 1):
        if len(row) != len(header):
            raise InputError(f"{len(row)} fields where the header has {len(header)}",
                             source=str(path), row=i)
    out = {}
    for name in required:
        j = header.index(name)
        cells = [row[j] for row in data]
        try:
            values = np.array(cells, dtype=float)
        except ValueError:
            values = None
        bad = (np.arange(len(cells)) if values is None else np.flatnonzero(~np.isfinite(values)))
        for i in bad:
            try:
                ok = math.isfinite(float(cells[i]))
            except ValueError:
                ok = False
            if not ok:
                raise InputError(f"not a finite number: {cells[i]!r}", source=str(path),
                                 row=int(i) + 1, column=name)
        out[name] = values if values is not None else np.array(cells, dtype=float)
    return out, notes


def load_run(run_dir: str | Path) -> Run:
    """Read one run directory (config.yaml, metrics.csv, eval.csv if present).

    Raises:
        InputError: unreadable config, a missing column, a non-numeric or non-finite value,
            episodes that do not run 1, 2, 3, ..., or a success outside [0, 1]; the message
            names the file, the row and the column.
    """
    from dualarm.training.config import TrainConfig
    from dualarm.training.run_dir import RunPaths

    paths = RunPaths(run_dir)
    config = TrainConfig.load(paths.config)
    m, notes = _read_columns(paths.metrics, METRICS_READ)
    episode = m["episode"]
    wrong = np.flatnonzero(episode != np.arange(1, len(episode) + 1))
    if wrong.size:
        i = int(wrong[0])
        raise InputError(f"episodes must run 1, 2, 3, ... without gaps; found {episode[i]:g} "
                         f"where {i + 1} was expected", source=str(paths.metrics), row=i + 1,
                         column="episode")
    off = np.flatnonzero((m["success"] < 0) | (m["success"] > 1))
    if off.size:
        raise InputError(f"success must be 0 or 1, got {m['success'][off[0]]:g}",
                         source=str(paths.metrics), row=int(off[0]) + 1, column="success")
    if paths.eval.is_file():
        e, eval_notes = _read_columns(paths.eval, EVAL_READ)
        notes += eval_notes
    else:
        e = {name: np.zeros(0) for name in EVAL_READ}
    return Run(path=paths.root, condition=config.condition, seed=config.seed,
               planned_episodes=config.episodes, wall_time_s=m["wall_time_s"],
               return_total=m["return_total"], success=m["success"],
               eval_episode=e["episode"].astype(int), eval_success=e["success_rate"],
               notes=tuple(notes))


def summarize_condition(condition: str, runs: list[Run], window: int = 100,
                        target: float = TARGET_SUCCESS) -> ConditionSummary:
    """Per-seed curves and quantities of one condition, on the episodes common to its runs.

    Args:
        condition: the condition of every run in ``runs``.
        runs: at least one run, each with at least one episode.
        window: moving-average window, episodes.
        target: success rate of "episodes to target".
    """
    n = min(r.episodes for r in runs)
    ma_return = np.stack([trailing_mean(r.return_total[:n], window)[0] for r in runs])
    ma_success = np.stack([trailing_mean(r.success[:n], window)[0] for r in runs])
    conv = [convergence(r.return_total[:n], window) for r in runs]
    conv_time = [r.wall_time_s[c.episode - 1] if c.converged else None for r, c in zip(runs, conv)]
    final_eval = []
    for r in runs:
        inside = r.eval_episode <= n
        final_eval.append(r.eval_success[inside][-1] if inside.any() else None)
    common = sorted(set.intersection(*(set(r.eval_episode[r.eval_episode <= n].tolist())
                                       for r in runs)))
    eval_success = np.array([[r.eval_success[r.eval_episode == ep][-1] for ep in common]
                             for r in runs]).reshape(len(runs), len(common))
    return ConditionSummary(
        condition=condition, runs=runs, episodes=n, ma_return=ma_return, ma_success=ma_success,
        convergence=conv,
        episodes_to_target=SeedStat.of([episodes_to_target(r.success[:n], target, window)
                                        for r in runs]),
        convergence_episode=SeedStat.of([c.episode for c in conv]),
        convergence_time_s=SeedStat.of(conv_time),
        max_avg_success=SeedStat.of([max_average(r.success[:n], window) for r in runs]),
        final_eval_success=SeedStat.of(final_eval),
        eval_episode=np.array(common, dtype=int), eval_success=eval_success)


def build_report(comparison_dir: str | Path, window: int = 100, target: float = TARGET_SUCCESS) -> Report:
    """Read every run under ``comparison_dir`` and summarise each condition.

    Args:
        comparison_dir: a directory whose run directories (``config.yaml`` + ``metrics.csv``)
            lie at most two levels below it (``dualarm compare`` writes ``DIR/runs/<name>/``).
        window: moving-average window, episodes, >= 1.
        target: success rate of "episodes to target", in (0, 1].

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
    runs = sorted((load_run(d) for d in dirs),
                  key=lambda r: (CONDITIONS.index(r.condition), r.seed, str(r.path)))
    notes = []
    for r in runs:
        where = _relative(r.path, root)
        notes += [f"{where}: {n}" for n in r.notes]
        if r.partial:
            notes.append(f"{where}: partial run, {r.episodes} of {r.planned_episodes} planned "
                         "episodes (still running or stopped)")
    seen: dict[tuple[str, int], Path] = {}
    for r in runs:
        key = (r.condition, r.seed)
        if key in seen:
            notes.append(f"{_relative(r.path, root)} and {_relative(seen[key], root)} are both "
                         f"{r.condition} seed {r.seed}; both are counted")
        seen.setdefault(key, r.path)
    empty = [r for r in runs if r.episodes == 0]
    notes += [f"{_relative(r.path, root)}: no episodes logged yet; left out" for r in empty]
    runs_used = [r for r in runs if r.episodes > 0]
    if not runs_used:
        raise InputError("none of its runs has logged an episode yet", source=str(root))
    conditions = {}
    for c in CONDITIONS:
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
    lengths = {s.episodes for s in conditions.values()}
    if len(lengths) > 1:
        notes.append("the conditions cover different episode ranges ("
                     + ", ".join(f"{c} {s.episodes}" for c, s in conditions.items())
                     + "): a condition cannot reach a criterion beyond its own range")
    ratios = {q: condition_ratios({c: (s.stat(q).mean if s.stat(q).reached else None)
                                   for c, s in conditions.items()})
              for q in RATIO_QUANTITIES}
    for s in conditions.values():
        for q in ("episodes_to_target", "convergence_episode"):
            st = s.stat(q)
            if st.partial:
                notes.append(f"{s.condition}: only {st.reached} of {st.seeds} seeds reached "
                             f"{'the target' if q == 'episodes_to_target' else 'convergence'}; "
                             "its mean and ratios are over those seeds (marked †)")
    return Report(source=root, window=int(window), target=float(target), runs=runs,
                  conditions=conditions, ratios=ratios, notes=notes)


def _relative(path: Path, root: Path) -> str:
    try:
        rel = path.relative_to(root)
        return str(rel) if str(rel) != "." else path.name
    except ValueError:
        return str(path)


# ----------------------------------------------------------------------------- tables

def paper_ratio(quantity: str, pair: tuple[str, str]) -> tuple[float, bool]:
    """The paper's ratio of ``quantity`` for ``pair`` and whether its text quotes it (else it
    is derived from the paper's per-condition values)."""
    quoted = PAPER_QUOTED_RATIOS.get((quantity, pair))
    if quoted is not None:
        return quoted, True
    values = PAPER[quantity]
    return values[pair[0]] / values[pair[1]], False


def _paper_value(report: Report, quantity: str, condition: str) -> float | None:
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


def _num(x: float | None, digits: int) -> str:
    return "" if x is None or not math.isfinite(x) else f"{x:.{digits}f}"


def _csv_num(x: float | None) -> str:
    return "" if x is None or not math.isfinite(x) else f"{x:.10g}"


_DIGITS = {"episodes_to_target": 0, "convergence_episode": 0, "convergence_time_s": 0,
           "max_avg_success": 3, "final_eval_success": 3}


def _cell(stat: SeedStat, quantity: str, count: bool = True) -> str:
    d = _DIGITS[quantity]
    if stat.reached == 0:
        what = "not converged" if quantity.startswith("convergence") else "not reached"
        return f"{what} (0/{stat.seeds})" if count else "n/a"
    text = _num(stat.mean, d)
    if math.isfinite(stat.ci95):
        text += f" ± {_num(stat.ci95, d)}"
    if count:
        text += f" ({stat.reached}/{stat.seeds}{' †' if stat.partial else ''})"
    return text


def summary_rows(report: Report) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the human-readable per-condition table (strings)."""
    t = report.target
    header = ["condition", "seeds", "episodes compared", f"episodes to success {t:g}",
              "episodes to convergence", "time to convergence, s", "max average success",
              "final evaluation success", f"paper: to {TARGET_SUCCESS:g}", "paper: convergence",
              "paper: time, s", "paper: max success"]
    rows = []
    for c, s in report.conditions.items():
        paper = [_paper_value(report, q, c) for q in ("episodes_to_target", "convergence_episode",
                                                      "convergence_time_s", "max_avg_success")]
        rows.append([
            CONDITION_NAMES[c] + f" ({c})", str(s.seeds),
            f"1-{s.episodes}" + (" (common range)" if s.truncated else ""),
            _cell(s.episodes_to_target, "episodes_to_target"),
            _cell(s.convergence_episode, "convergence_episode"),
            _cell(s.convergence_time_s, "convergence_time_s"),
            _cell(s.max_avg_success, "max_avg_success", count=False),
            _cell(s.final_eval_success, "final_eval_success", count=False),
            *("" if v is None else f"{v:g}" for v in paper)])
    return header, rows


def ratio_rows(report: Report) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the ratio table: quantity, ratio, ours, the paper's, remarks."""
    header = ["quantity", "ratio", "this comparison", "paper", "remarks"]
    rows = []
    for q in RATIO_QUANTITIES:
        for pair in RATIO_PAIRS:
            ours = report.ratios[q][pair]
            paper, quoted = paper_ratio(q, pair)
            if q == "episodes_to_target" and not math.isclose(report.target, TARGET_SUCCESS):
                paper_text = f"({TARGET_SUCCESS:g} only)"
            else:
                paper_text = f"{paper:.2f}" + ("" if quoted else " (derived)")
            note = ratio_note(report, q, pair)
            name = QUANTITY_NAMES[q] + (f" {report.target:g}" if q == "episodes_to_target" else "")
            rows.append([name, f"{pair[0]}/{pair[1]}",
                         "n/a" if ours is None else f"{ours:.2f}" + (" †" if note else ""),
                         paper_text, note])
    return header, rows


def run_rows(report: Report) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the per-run table."""
    header = ["condition", "seed", "episodes", "wall time, s", f"to success {report.target:g}",
              "converged at", "directory", "remarks"]
    rows = []
    for r in report.runs:
        s = report.conditions.get(r.condition)
        k = next((i for i, x in enumerate(s.runs) if x is r), None) if s is not None else None
        to_target = conv = ""
        remarks = list(r.notes)
        if k is not None:
            v = s.episodes_to_target.values[k]
            to_target = f"{v:.0f}" if math.isfinite(v) else "not reached"
            c = s.convergence[k]
            conv = str(c.episode) if c.converged else "not converged"
            if not c.converged:
                remarks.append(c.reason)
        if r.partial:
            remarks.append(f"partial: {r.episodes} of {r.planned_episodes} planned")
        wall = f"{r.wall_time_s[-1]:.0f}" if r.episodes else "0"
        rows.append([r.condition, str(r.seed), str(r.episodes), wall, to_target, conv,
                     _relative(r.path, report.source), "; ".join(remarks)])
    return header, rows


def csv_table(report: Report) -> str:
    """``table.csv``: one row per condition, plain numbers (empty = not available)."""
    cols = ["condition", "seeds", "episodes_compared", "target", "window"]
    for q in ("episodes_to_target", "convergence_episode", "convergence_time_s"):
        cols += [f"{q}_mean", f"{q}_ci95", f"{q}_seeds_reached"]
    for q in ("max_avg_success", "final_eval_success"):
        cols += [f"{q}_mean", f"{q}_ci95", f"{q}_seeds"]
    cols += [f"paper_{q}" for q in ("episodes_to_target", "convergence_episode",
                                    "convergence_time_s", "max_avg_success")]
    for q in RATIO_QUANTITIES:
        for den in ("none", "single"):
            cols += [f"{q}_ratio_vs_{den}", f"paper_{q}_ratio_vs_{den}"]
    text = io.StringIO()
    w = csv.writer(text, lineterminator="\n")
    w.writerow(cols)
    for c, s in report.conditions.items():
        row = [c, s.seeds, s.episodes, f"{report.target:g}", report.window]
        for q in ("episodes_to_target", "convergence_episode", "convergence_time_s",
                  "max_avg_success", "final_eval_success"):
            st = s.stat(q)
            row += [_csv_num(st.mean), _csv_num(st.ci95), st.reached]
        row += [_csv_num(_paper_value(report, q, c)) for q in (
            "episodes_to_target", "convergence_episode", "convergence_time_s", "max_avg_success")]
        for q in RATIO_QUANTITIES:
            for den in ("none", "single"):
                pair = (c, den)
                if pair in RATIO_PAIRS:
                    paper = paper_ratio(q, pair)[0]
                    if q == "episodes_to_target" and not math.isclose(report.target, TARGET_SUCCESS):
                        paper = None
                    row += [_csv_num(report.ratios[q][pair]), _csv_num(paper)]
                else:
                    row += ["", ""]
        w.writerow(row)
    return text.getvalue()


def _md_table(header: list[str], rows: list[list[str]]) -> str:
    def esc(x: str) -> str:
        return x.replace("|", "\\|")
    lines = ["| " + " | ".join(map(esc, header)) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(map(esc, r)) + " |" for r in rows]
    return "\n".join(lines)


def _html_table(header: list[str], rows: list[list[str]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "\n".join("<tr>" + "".join(f"<td>{html.escape(x)}</td>" for x in r) + "</tr>"
                     for r in rows)
    return f"<table>\n<thead><tr>{head}</tr></thead>\n<tbody>\n{body}\n</tbody>\n</table>"


def definitions(report: Report) -> list[str]:
    """The definitions behind the numbers, one paragraph each, with this report's settings."""
    w, t = report.window, report.target
    return [
        f"Moving average: the mean of the last {w} training episodes up to and including the "
        f"episode (fewer at the start of a run; the quantities below use full windows only, "
        f"from episode {w} on). Curves are per seed; the figures show their mean over seeds.",
        f"Episodes to success {t:g}: the first episode at which the {w}-episode moving average "
        "of training success (with exploration noise) is at least "
        f"{t:g}. Seeds that never reach it are counted, not averaged (k/n).",
        f"Convergence of the return curve: the final level L is the mean of the {w}-episode "
        "moving average of the return over the last 10% of the run; the band is L ± tol with "
        "tol = max(5% of the range of the moving average, 3 standard errors of a "
        f"{w}-episode mean, from the spread of the returns over the last 10%). A run has "
        "converged if its moving average stays inside the band over the whole last 10% and "
        "the least-squares line through it there changes by at most tol; the convergence "
        "episode is the first episode from which it stays inside the band to the end. Time to "
        "convergence is the run's cumulative training wall time at that episode.",
        "Max average success: the largest full-window moving average of training success. "
        "Final evaluation success: the success rate of the last deterministic evaluation "
        "(eval.csv) within the compared episode range.",
        "Mean ± 95% CI: the mean over the seeds that reached the criterion and the half-width "
        "t(0.975, n-1)·s/√n of the Student-t interval (s: sample standard deviation over those "
        "n seeds); no interval with one seed. † marks a mean over only some of the seeds.",
        "Ratios: quotients of the per-condition means (e.g. multi/none of episodes to "
        "convergence); not available when a condition has no seed that reached the criterion. "
        "Paper values marked (derived) are not quoted in its text but computed from its "
        "per-condition values.",
        "Runs of one condition with different lengths are compared over their common episode "
        "range (1 to the shortest run's length); the longer runs' later episodes are not used.",
    ]


# ----------------------------------------------------------------------------- writing

FIGURES = {"fig6": "fig6_return.png", "fig7": "fig7_success.png", "fig8": "fig8_convergence_time.png"}


def _write_text(path: Path, text: str) -> None:
    with atomic_open(path) as f:
        f.write(text.encode())


def markdown(report: Report) -> str:
    """``table.md``: the per-condition table, the ratios, the notes and the definitions."""
    parts = [f"# Comparison report: {report.source}", "",
             f"Moving average over {report.window} episodes, success target {report.target:g}, "
             "mean ± 95% CI over seeds (k/n: seeds that reached the criterion).", "",
             _md_table(*summary_rows(report)), "", "## Ratios between conditions", "",
             _md_table(*ratio_rows(report)), "", "## Runs", "", _md_table(*run_rows(report))]
    if report.notes:
        parts += ["", "## Notes", ""] + [f"- {n}" for n in report.notes]
    parts += ["", "## Definitions", ""] + [f"- {d}" for d in definitions(report)]
    return "\n".join(parts) + "\n"


def html_page(report: Report) -> str:
    """``index.html``: figures (PNG files beside it), tables, notes, definitions, runs."""
    style = ("body{font-family:sans-serif;max-width:1200px;margin:2em auto;padding:0 1em}"
             "table{border-collapse:collapse;margin:1em 0;font-size:90%}"
             "td,th{border:1px solid #bbb;padding:3px 7px;text-align:left}"
             "th{background:#eee}img{max-width:100%}")
    figs = [("fig6", "Fig. 6. Average cumulative return"),
            ("fig7", "Fig. 7. Average success rate (training) and evaluation success"),
            ("fig8", "Fig. 8. Training time (and episodes) to convergence of the return curve")]
    body = [f"<h1>Comparison report</h1><p>{html.escape(str(report.source))}: "
            f"{len(report.runs)} runs. Moving average over {report.window} episodes, success "
            f"target {report.target:g}, mean ± 95% CI over seeds.</p>",
            "<h2>Summary</h2>", _html_table(*summary_rows(report)),
            "<h2>Ratios between conditions</h2>", _html_table(*ratio_rows(report))]
    if report.notes:
        body += ["<h2>Notes</h2><ul>"] + [f"<li>{html.escape(n)}</li>" for n in report.notes]
        body += ["</ul>"]
    for key, caption in figs:
        body.append(f'<figure><img src="{FIGURES[key]}" alt="{html.escape(caption)}">'
                    f"<figcaption>{html.escape(caption)}</figcaption></figure>")
    body += ["<h2>Definitions</h2>"] + [f"<p>{html.escape(d)}</p>" for d in definitions(report)]
    body += ["<h2>Runs</h2>", _html_table(*run_rows(report))]
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>dualarm comparison report</title><style>{style}</style></head><body>\n"
            + "\n".join(body) + "\n</body></html>\n")


def save_report(report: Report, out: str | Path) -> Path:
    """Write the figures, table.csv, table.md and index.html of ``report`` into ``out``
    (created if missing), each atomically, index.html last. Returns the path of index.html."""
    from dualarm.experiments import report_plots

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    report_plots.plot_return(report, out / FIGURES["fig6"])
    report_plots.plot_success(report, out / FIGURES["fig7"])
    report_plots.plot_convergence_time(report, out / FIGURES["fig8"])
    _write_text(out / "table.csv", csv_table(report))
    _write_text(out / "table.md", markdown(report))
    index = out / "index.html"
    _write_text(index, html_page(report))
    return index


def write_report(comparison_dir: str | Path, out: str | Path | None = None, window: int = 100,
                 target: float = TARGET_SUCCESS) -> Path:
    """Write the report of a comparison directory: Figs. 6-8 (PNG), table.md, table.csv and
    index.html, each atomically, index.html last.

    Args:
        comparison_dir: directory holding the run directories (see ``build_report``).
        out: output directory (default: ``comparison_dir/report``).
        window: moving-average window, episodes, >= 1.
        target: success rate of "episodes to target", in (0, 1].

    Returns:
        The path of index.html.

    Raises:
        InputError: no run directory, or a run directory with a missing column or a
            non-numeric value (the message names the file and the column).
    """
    report = build_report(comparison_dir, window, target)
    return save_report(report, Path(out) if out is not None else Path(comparison_dir) / "report")
