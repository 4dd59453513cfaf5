"""The run directories of a comparison, read: each run's config, metrics.csv and eval.csv
as arrays (``load_run``), found under a comparison directory (``find_run_dirs``)."""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dualarm.errors import InputError

#: Columns a run's metrics.csv must have (the others are not read).
METRICS_READ = ("episode", "wall_time_s", "return_total", "success")

#: The eval.csv column of each set of actors a report can read: "policy", the run's own
#: policy (``algo.eval_actor``), and "average", the averaged actors a run with
#: ``policy_average`` > 0 evaluates beside its own.
EVAL_SUCCESS_COLUMNS = {"policy": "success_rate", "average": "average_success_rate"}

#: Columns an eval.csv must have to be read for its policy (``load_run``'s default).
EVAL_READ = ("episode", EVAL_SUCCESS_COLUMNS["policy"])


@dataclass(frozen=True, eq=False)
class Run:
    """The curves of one training run directory.

    Attributes:
        path: the run directory.
        condition: "none", "single", "multi" or "demos" (from config.yaml: a run with
            recordings as demonstrations is "demos", ``TrainConfig.compared_condition``).
        seed: the run's seed.
        planned_episodes: ``episodes`` of its config (the run is partial if it has fewer).
        wall_time_s: (n,) cumulative training time at the end of each episode, s.
        return_total: (n,) return of each training episode, both arms.
        success: (n,) 1 if the training episode succeeded, else 0.
        eval_episode: (k,) training episodes after which an evaluation ran.
        eval_success: (k,) success rate of each evaluation, in [0, 1].
        notes: remarks on reading it (e.g. an incomplete last row dropped).
        later_starts: training episodes may start at later sub-tasks (``starts.probs``), so
            their success is not the task's from the normal reset (evaluations are).
        stopped: the run ended by reaching its config's ``stop_at`` at an evaluation: it is
            done, not partial, with fewer episodes than planned.
        stop_at: its config's ``stop_at`` (an evaluation success rate), or None.
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
    later_starts: bool = False
    stopped: bool = False
    stop_at: float | None = None

    @property
    def measured_on_evals(self) -> bool:
        """Whether its success is read from its evaluations rather than its training episodes:
        training episodes that start at later sub-tasks succeed without the task being
        learned, and a run with a ``stop_at`` ends as soon as an evaluation reaches it, before
        the noisier training success can."""
        return self.later_starts or self.stop_at is not None

    @property
    def episodes(self) -> int:
        """Training episodes logged in metrics.csv."""
        return len(self.success)

    @property
    def partial(self) -> bool:
        """True when the run logged fewer episodes than its config asks for, and did not end
        by reaching its ``stop_at``."""
        return self.episodes < self.planned_episodes and not self.stopped


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


def load_run(run_dir: str | Path, actors: str = "policy") -> Run:
    """Read one run directory (config.yaml, metrics.csv, eval.csv if present).

    ``actors`` picks the evaluations read (``EVAL_SUCCESS_COLUMNS``): "policy" the run's
    policy (``success_rate``), "average" the averaged actors evaluated beside it
    (``average_success_rate``, which the run's eval.csv must then have).

    Raises:
        InputError: unreadable config, a missing column, a non-numeric or non-finite value,
            episodes that do not run 1, 2, 3, ..., or a success outside [0, 1]; the message
            names the file, the row and the column.
    """
    from dualarm.training.config import TrainConfig
    from dualarm.training.run_dir import RunPaths

    if actors not in EVAL_SUCCESS_COLUMNS:
        raise InputError(f"actors must be one of {', '.join(EVAL_SUCCESS_COLUMNS)}, got {actors!r}")
    column = EVAL_SUCCESS_COLUMNS[actors]
    paths = RunPaths(run_dir)
    config = TrainConfig.load_saved(paths.config)
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
    policy = EVAL_SUCCESS_COLUMNS["policy"]       # the column a run's stop_at reads
    names = tuple(dict.fromkeys(("episode", column, policy)))
    if paths.eval.is_file():
        e, eval_notes = _read_columns(paths.eval, names)
        notes += eval_notes
    else:
        e = {name: np.zeros(0) for name in names}
    stopped = (config.stop_at is not None and e[policy].size > 0
               and bool(e[policy][-1] >= config.stop_at))
    return Run(path=paths.root, condition=config.compared_condition, seed=config.seed,
               planned_episodes=config.episodes, wall_time_s=m["wall_time_s"],
               return_total=m["return_total"], success=m["success"],
               eval_episode=e["episode"].astype(int), eval_success=e[column],
               notes=tuple(notes), later_starts=config.starts.later, stopped=stopped,
               stop_at=config.stop_at)
