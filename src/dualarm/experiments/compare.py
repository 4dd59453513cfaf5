"""Conditions x seeds of training runs in one directory: plan, manifest, resume state, driver.

    DIR/comparison.yaml          the manifest: conditions, seeds, episodes, base TrainConfig
    DIR/constraints/<cond>.yaml  copies of the --constraints-dir files the runs use (if any)
    DIR/runs/<cond>-seed<s>/     one run directory of ``dualarm train`` per (condition, seed),
                                 plus ``done.yaml`` once its ``run()`` has returned

A run is *finished* when its ``done.yaml`` counts at least the comparison's episodes (or says
it reached its ``stop_at``),
*partial* when it holds a ``config.yaml`` (it resumes from its latest checkpoint), and *new*
otherwise. Running a comparison again skips the finished runs, resumes the partial ones and
starts the new ones; a larger ``episodes`` makes every run partial again (extended), and new
conditions or seeds add runs. Anything else that differs from the manifest is an error.
"""

from __future__ import annotations

import secrets
import sys
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from dualarm.atomic import atomic_copy, atomic_open
from dualarm.constraints.constraint_set import same_constraints
from dualarm.errors import InputError
from dualarm.experiments.backends import MANIFEST, RunOutcome, RunTask, logged_episodes, read_done
from dualarm.locks import DirectoryLock
from dualarm.task import (CONDITIONS, COMPARED_CONDITIONS, DEMOS_CONDITION, GUIDED_CONDITIONS,
                          MAX_SEED, guide_condition)
from dualarm.training.config import TrainConfig
from dualarm.training.run_dir import RunPaths
from dualarm.yaml_io import read_yaml

DEFAULT_SEEDS = (0, 1, 2)
MANIFEST_FORMAT = "dualarm-comparison"
MANIFEST_VERSION = 1
__all__ = ["CompareRequest", "Comparison", "CompareResult", "RunPlan", "prepare", "load_manifest",
           "save_manifest", "run_state", "logged_episodes", "run_comparison", "compare",
           "task_for", "parse_conditions", "parse_seeds", "differences", "base_dict", "merged_grid"]

#: TrainConfig fields set per run (not part of the comparison's base config).
PER_RUN = ("condition", "seed", "episodes", "constraints")


@dataclass(frozen=True)
class CompareRequest:
    """What a ``dualarm compare`` invocation asks for; None means "as in the manifest" (or
    the default for a new comparison).

    Attributes:
        conditions: guidance conditions to include (added to the manifest's).
        seeds: seeds to include (added to the manifest's), each >= 0.
        episodes: training episodes per run; may grow, never shrink, an existing comparison.
        base: base TrainConfig of every run (its condition, seed and constraints are ignored,
            its episodes used only when ``episodes`` is None for a new comparison); None for
            a new comparison is the recipe (``TrainConfig.recipe()``).
        base_source: where ``base`` came from (named in conflict messages).
        constraints_dir: a folder with ``single.yaml`` and/or ``multi.yaml``; None uses the
            shipped files (new comparison) or the comparison's own copies.
        demos_dir: the demonstration folder of the ``demos`` condition (recordings with
            gripper events, labels.csv, scene.csv); asking for it adds that condition. None:
            the shipped set, if the condition is asked for.
        stop_at: every run ends after the first evaluation that reaches this success rate
            (``TrainConfig.stop_at``); "none": no run stops early; None: as the base says.
    """

    conditions: tuple[str, ...] | None = None
    seeds: tuple[int, ...] | None = None
    episodes: int | None = None
    base: TrainConfig | None = None
    base_source: str = "--config"
    constraints_dir: Path | None = None
    demos_dir: Path | None = None
    stop_at: float | str | None = None

    def with_stop(self, base: TrainConfig | None) -> TrainConfig | None:
        """``base`` with ``stop_at`` applied (None stays None)."""
        if base is None or self.stop_at is None:
            return base
        return base.with_(stop_at=None if self.stop_at == "none" else float(self.stop_at))


@dataclass(frozen=True)
class RunPlan:
    """One (condition, seed) run of a comparison.

    Attributes:
        name: "<condition>-seed<seed>", the run directory's name.
        config: the run's full TrainConfig (``episodes`` is the target total).
        path: its run directory.
        state: "finished", "partial" or "new" (see ``run_state``).
    """

    name: str
    condition: str
    seed: int
    config: TrainConfig
    path: Path
    state: str


@dataclass(frozen=True)
class Comparison:
    """A comparison as recorded in its manifest (see the module docstring).

    Attributes:
        root: the comparison directory (absolute).
        id: random id of the comparison (tells a Ray node whether it sees ``root``).
        conditions, seeds: the grid of runs, in canonical order.
        episodes: training episodes of every run.
        base: the base TrainConfig (per-run fields at their defaults).
        constraints_dir: the folder the constraint files were copied from, or None for the
            shipped files.
        demos_dir: the demonstration folder of the ``demos`` condition (None without it).
    """

    root: Path
    id: str
    conditions: tuple[str, ...]
    seeds: tuple[int, ...]
    episodes: int
    base: TrainConfig
    constraints_dir: Path | None = None
    demos_dir: Path | None = None

    @property
    def manifest_path(self) -> Path:
        return self.root / MANIFEST

    def constraints_path(self, condition: str) -> Path | None:
        """The comparison's copy of the constraints of ``condition`` (of its guide condition:
        ``demos`` uses multi's); None for "none" or the shipped file (a run config's
        ``constraints: null`` means the shipped one)."""
        condition = guide_condition(condition)
        if condition == "none" or self.constraints_dir is None:
            return None
        return self.root / "constraints" / f"{condition}.yaml"

    def run_config(self, condition: str, seed: int) -> TrainConfig:
        """The TrainConfig of one run: the base with the run's condition, seed, episodes and
        constraints, and for ``demos`` the recordings (``TrainConfig.demos.folder``) with the multi
        guide term."""
        path = self.constraints_path(condition)
        demos = str(self.demos_dir) if condition == DEMOS_CONDITION else None
        return self.base.with_(condition=guide_condition(condition), seed=seed,
                               episodes=self.episodes, constraints=str(path) if path else None,
                               demos=demos)

    def runs(self) -> list[RunPlan]:
        """Every (condition, seed) run, conditions first, with its current state."""
        plans = []
        for condition in self.conditions:
            for seed in self.seeds:
                name = f"{condition}-seed{seed}"
                path = self.root / "runs" / name
                plans.append(RunPlan(name, condition, seed, self.run_config(condition, seed),
                                     path, run_state(path, self.episodes)))
        return plans

    def to_manifest(self) -> dict:
        return {"format": MANIFEST_FORMAT, "version": MANIFEST_VERSION, "id": self.id,
                "conditions": list(self.conditions), "seeds": list(self.seeds),
                "episodes": self.episodes,
                "constraints_dir": str(self.constraints_dir) if self.constraints_dir else None,
                "demos_dir": str(self.demos_dir) if self.demos_dir else None,
                "base": base_dict(self.base)}


@dataclass
class CompareResult:
    """What a comparison invocation did.

    Attributes:
        skipped: names of the runs already finished before it started.
        outcomes: one per run it trained, in the order they ended.
    """

    comparison: Comparison
    skipped: list[str] = field(default_factory=list)
    outcomes: list[RunOutcome] = field(default_factory=list)

    @property
    def failed(self) -> list[RunOutcome]:
        return [o for o in self.outcomes if not o.ok]


# ------------------------------------------------------------------ state
def run_state(run_dir: str | Path, episodes: int) -> str:
    """"finished" (its done marker counts >= ``episodes``, or says the run reached its
    ``stop_at``), "partial" (it holds a ``config.yaml``: resume it) or "new" (start it)."""
    run_dir = Path(run_dir)
    done = read_done(run_dir)
    if done is not None and (done["episodes"] >= episodes or done.get("stopped") is True):
        return "finished"
    return "partial" if RunPaths(run_dir).config.exists() else "new"


def base_dict(config: TrainConfig) -> dict:
    """``config`` as plain YAML-safe data without the per-run fields (``PER_RUN``)."""
    d = {k: v for k, v in config.to_dict().items() if k not in PER_RUN}
    return yaml.safe_load(yaml.safe_dump(d))


def _flatten(d, prefix: str = "") -> dict:
    if not isinstance(d, dict):
        return {prefix: d}
    out = {}
    for k, v in d.items():
        out.update(_flatten(v, f"{prefix}.{k}" if prefix else str(k)))
    return out


def differences(a: dict, b: dict) -> list[tuple[str, object, object]]:
    """(dotted field, value in a, value in b) for every field where two nested dicts differ."""
    fa, fb = _flatten(a), _flatten(b)
    return [(k, fa.get(k), fb.get(k)) for k in sorted(set(fa) | set(fb)) if fa.get(k) != fb.get(k)]


# --------------------------------------------------------------- manifest
def load_manifest(root: str | Path) -> Comparison | None:
    """The comparison recorded in ``root/comparison.yaml``, or None if there is none.

    Raises:
        InputError: the manifest is unreadable, not a comparison manifest, or invalid.
    """
    root = Path(root).resolve()
    path = root / MANIFEST
    if not path.exists():
        return None
    data = read_yaml(path, "the comparison manifest")
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT:
        raise InputError("not a dualarm comparison manifest", source=str(path))
    if data.get("version") != MANIFEST_VERSION:
        raise InputError(f"manifest version {data.get('version')} is not supported "
                         f"(this code reads {MANIFEST_VERSION})", source=str(path))
    try:
        base = TrainConfig.from_dict(data["base"], where=f"{path}: base", base=TrainConfig.paper())
        comparison = Comparison(
            root=root, id=str(data["id"]),
            conditions=_conditions(data["conditions"], f"{path}: conditions"),
            seeds=_seeds(data["seeds"], f"{path}: seeds"),
            episodes=_episodes(data["episodes"], f"{path}: episodes"),
            base=base,
            constraints_dir=Path(data["constraints_dir"]) if data.get("constraints_dir") else None,
            demos_dir=Path(data["demos_dir"]) if data.get("demos_dir") else None)
    except KeyError as exc:
        raise InputError(f"missing field {exc}", source=str(path)) from None
    return comparison


def save_manifest(comparison: Comparison) -> None:
    """Write ``comparison.yaml`` atomically."""
    with atomic_open(comparison.manifest_path) as f:
        f.write(yaml.safe_dump(comparison.to_manifest(), sort_keys=False).encode())


def _conditions(values, where: str) -> tuple[str, ...]:
    values = list(values)
    bad = [c for c in values if c not in COMPARED_CONDITIONS]
    if bad or not values:
        raise InputError(f"{where}: conditions must be among {', '.join(COMPARED_CONDITIONS)}, "
                         f"got {values}")
    return tuple(c for c in COMPARED_CONDITIONS if c in values)


def _seeds(values, where: str) -> tuple[int, ...]:
    values = list(values)
    if not values or any(not isinstance(s, int) or isinstance(s, bool) or not 0 <= s <= MAX_SEED
                         for s in values):
        raise InputError(f"{where}: seeds must be integers in 0..{MAX_SEED}, got {values}")
    return tuple(sorted(set(values)))


def merged_grid(existing: "Comparison | None",
                request: CompareRequest) -> tuple[tuple[str, ...], tuple[int, ...]]:
    """The (conditions, seeds) of the comparison ``prepare`` makes of ``request``: for a new
    one (``existing`` None) the request's, by default every condition and ``DEFAULT_SEEDS``;
    for an existing one its own joined with the request's. A ``demos_dir`` adds the ``demos``
    condition. Conditions in ``COMPARED_CONDITIONS`` order, seeds sorted.

    Raises:
        InputError: a condition or seed is invalid (named as --conditions / --seeds).
    """
    asked = tuple(request.conditions or ())
    if request.demos_dir is not None:
        asked += (DEMOS_CONDITION,)
    if existing is None:
        if request.conditions is None:
            asked += CONDITIONS
        return (_conditions(asked, "--conditions"),
                _seeds(request.seeds if request.seeds is not None else DEFAULT_SEEDS, "--seeds"))
    return (_conditions(set(existing.conditions) | set(asked), "--conditions"),
            _seeds(set(existing.seeds) | set(request.seeds or ()), "--seeds"))


def _episodes(value, where: str) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or value < 1:
        raise InputError(f"{where}: episodes must be an integer >= 1, got {value!r}")
    return value


# ---------------------------------------------------------------- prepare
def prepare(root: str | Path, request: CompareRequest) -> Comparison:
    """Create the comparison in ``root``, or merge ``request`` into the one there; copy the
    constraint files it needs, check the existing run directories, write the manifest.

    Nothing is written unless every check passes.

    Raises:
        InputError: the request conflicts with the manifest (the field is named), a
            constraints file is missing or invalid, a run directory was made with other
            settings, or ``root`` holds runs but no manifest.
    """
    root = Path(root).resolve()
    if root.exists() and not root.is_dir():
        raise InputError(f"{root}: not a directory")
    if RunPaths(root).config.exists():
        raise InputError(f"{root} is the directory of a training run: choose another -o for the "
                         "comparison (nothing was written)")
    existing = load_manifest(root)
    where = str(root / MANIFEST)
    if request.conditions is not None:
        _conditions(request.conditions, "--conditions")
    if request.seeds is not None:
        _seeds(request.seeds, "--seeds")
    if request.episodes is not None:
        _episodes(request.episodes, "--episodes")
    given_dir = request.constraints_dir.resolve() if request.constraints_dir is not None else None
    if given_dir is not None and not given_dir.is_dir():
        raise InputError(f"{given_dir}: --constraints-dir is not a directory")
    if request.base is not None and request.base.demos.recordings:
        raise InputError(f"{request.base_source}: field 'demos.folder' is set per run by the comparison: "
                         "give the folder as --demos DIR (the demos condition)")

    if existing is None:
        runs = root / "runs"
        if runs.is_dir() and any(runs.iterdir()):
            raise InputError(f"{runs} holds runs but {root} has no {MANIFEST}: not a comparison "
                             "directory of this version; choose another -o")
        base = request.with_stop(request.base or TrainConfig())
        conditions, seeds = merged_grid(None, request)
        comparison = Comparison(
            root=root, id=secrets.token_hex(8), conditions=conditions, seeds=seeds,
            episodes=request.episodes or base.episodes,
            base=TrainConfig.from_dict(base_dict(base), where=request.base_source,
                                      base=TrainConfig.paper()),
            constraints_dir=given_dir,
            demos_dir=_demos_dir(conditions, request.demos_dir, base))
    else:
        asked = request.with_stop(request.base or (existing.base if request.stop_at is not None
                                                   else None))
        if asked is not None:
            diff = differences(base_dict(existing.base), base_dict(asked))
            if diff:
                name, theirs, mine = diff[0]
                given = "--stop-at" if name == "stop_at" and request.stop_at else request.base_source
                raise InputError(f"field '{name}' is {theirs!r} in the comparison's base config but "
                                 f"{mine!r} in {given} (and {len(diff) - 1} more field(s) "
                                 "differ); run it with the same base config or choose another -o",
                                 source=where)
        if request.episodes is not None and request.episodes < existing.episodes:
            raise InputError(f"field 'episodes' is {existing.episodes}, --episodes {request.episodes} "
                             "would shorten the runs (runs are extended, never shortened)", source=where)
        if given_dir is not None and existing.constraints_dir is None:
            raise InputError(f"field 'constraints_dir': the comparison uses the shipped constraint "
                             f"files, not --constraints-dir {given_dir}", source=where)
        given_demos = request.demos_dir.resolve() if request.demos_dir is not None else None
        if (given_demos is not None and existing.demos_dir is not None
                and given_demos != existing.demos_dir):
            raise InputError(f"field 'demos_dir' is {str(existing.demos_dir)!r}, not --demos "
                             f"{given_demos}; choose another -o to compare other recordings",
                             source=where)
        conditions, seeds = merged_grid(existing, request)
        comparison = Comparison(
            root=root, id=existing.id, conditions=conditions, seeds=seeds,
            episodes=max(existing.episodes, request.episodes or 0),
            base=existing.base, constraints_dir=existing.constraints_dir,
            demos_dir=existing.demos_dir or _demos_dir(conditions, given_demos, existing.base))

    copies = _constraint_copies(comparison, given_dir)
    for plan in comparison.runs():
        _check_run_dir(plan)
    for condition, source in copies.items():
        atomic_copy(source, comparison.constraints_path(condition))
    save_manifest(comparison)
    return comparison


def _demos_dir(conditions: tuple[str, ...], given: Path | None, base: TrainConfig) -> Path | None:
    """The demonstration folder of the ``demos`` condition (``given``, or the shipped set),
    checked as training will read it (recordings, labels, and scene within ``base``'s task
    workspace); None without the condition.

    Raises:
        InputError: the folder, a recording, its labels or its scene is missing or bad.
    """
    if DEMOS_CONDITION not in conditions:
        return None
    from dualarm.demos.formats import DEFAULT_DEMO_DIR
    from dualarm.sim_demos.replay import load_replay_folder

    folder = (given or DEFAULT_DEMO_DIR).resolve()
    if not folder.is_dir():
        raise InputError(f"{folder}: --demos is not a directory")
    load_replay_folder(folder, base.task_config().workspace())
    return folder


def _constraint_copies(comparison: Comparison, given_dir: Path | None) -> dict[str, Path]:
    """Constraint files to copy into ``root/constraints`` ({condition: source}), after
    checking that every guided condition has one and that ``given_dir`` agrees with the
    copies already made."""
    if comparison.constraints_dir is None:
        return {}
    copies = {}
    guided = {guide_condition(c) for c in comparison.conditions} & set(GUIDED_CONDITIONS)
    for condition in (c for c in GUIDED_CONDITIONS if c in guided):
        copy = comparison.constraints_path(condition)
        source = (given_dir or comparison.constraints_dir) / f"{condition}.yaml"
        if copy.exists():
            if given_dir is not None and not same_constraints(source, copy):
                raise InputError(f"field 'constraints.{condition}': {source} differs from the "
                                 f"comparison's copy {copy}; choose another -o to compare other "
                                 "constraints", source=str(comparison.manifest_path))
            continue
        if not source.exists():
            raise InputError(f"{source}: no {condition}.yaml in the constraints directory "
                             f"(condition '{condition}' needs it; see `dualarm constraints extract`)")
        # read as the run will read it (a single-segment file for single, ...)
        comparison.base.with_(condition=condition, constraints=str(source)).load_constraints()
        copies[condition] = source
    return copies


def _check_run_dir(plan: RunPlan) -> None:
    """An existing run directory must have been made with the run's settings (but episodes)."""
    path = RunPaths(plan.path).config
    if not path.exists():
        return
    theirs_config = TrainConfig.load_saved(path)
    mine, theirs = plan.config.to_dict(), theirs_config.to_dict()
    for d in (mine, theirs):      # a run keeps its own copy of the constraints: compare contents
        d.pop("episodes"), d.pop("constraints")
    diff = differences(yaml.safe_load(yaml.safe_dump(theirs)), yaml.safe_load(yaml.safe_dump(mine)))
    if not diff and plan.config.condition != "none":
        here, there = plan.config.constraints_file(), theirs_config.constraints_file()
        if not same_constraints(there, here):
            diff = [("constraints", str(there), str(here))]
    if diff:
        name, there, here = diff[0]
        raise InputError(f"field '{name}' is {there!r} in this run but {here!r} in the comparison; "
                         "move the run away or choose another -o", source=str(path))


# ----------------------------------------------------------------- driver
def task_for(comparison: Comparison, plan: RunPlan) -> RunTask:
    """The backend task of a run (a partial run resumes with ``plan.config.episodes``)."""
    path = plan.config.constraints
    return RunTask(plan.name, str(comparison.root), comparison.id, plan.config.to_dict(),
                   Path(path).read_bytes() if path else None)


def _describe(outcome: RunOutcome) -> str:
    if not outcome.ok:
        return f"{outcome.name}: FAILED after {outcome.episodes} episodes: {outcome.error}"
    line = f"{outcome.name}: done, {outcome.episodes} episodes ({outcome.wall_time_s:.0f} s"
    line += f" on {outcome.node})" if outcome.node else ")"
    if outcome.last_eval:
        line += (f", last evaluation: success {outcome.last_eval['success_rate']:.2f}, "
                 f"return {outcome.last_eval['return_mean']:.1f}")
    return line


def episode_budget(logged: dict[str, int], ended: set[str], target: int) -> tuple[int, int]:
    """(done, most) for the progress bar: the episodes all runs have logged, and the most they
    can come to. A run that has ended counts what it logged (one stopped at ``stop_at`` ends
    before its budget, so the total shrinks as such runs end); the others count ``target``.

    Args:
        logged: run name -> episodes in its metrics.csv.
        ended: names of the runs that have ended.
        target: each run's episode budget.
    """
    done = sum(min(target, n) for n in logged.values())
    most = sum(min(target, n) if name in ended else target for name, n in logged.items())
    return done, most


def run_comparison(comparison: Comparison, backend, poll_s: float = 2.0, progress: bool = True,
                   stream=None) -> CompareResult:
    """Train every unfinished run of ``comparison`` on ``backend`` until all have ended.

    One progress bar counts the episodes logged by all runs (from the runs' ``metrics.csv``,
    polled every ``poll_s`` seconds; total = runs x episodes, less what the runs that ended at
    ``stop_at`` did not need, ``episode_budget``); a line is printed as each run ends. A
    failed run is reported and the others go on. On KeyboardInterrupt the runs in flight are
    stopped (their checkpoints remain) and it is re-raised.

    Args:
        backend: a ``LocalBackend`` or ``RayBackend`` (``capacity`` runs in flight at most).
        stream: where the bar and lines go (default: stderr).
    """
    from tqdm import tqdm

    stream = stream or sys.stderr
    plans = comparison.runs()
    result = CompareResult(comparison, skipped=[p.name for p in plans if p.state == "finished"])
    todo = [p for p in plans if p.state != "finished"]
    states = {s: sum(p.state == s for p in plans) for s in ("finished", "partial", "new")}
    print(f"comparison {comparison.root}: {len(plans)} runs of {comparison.episodes} episodes "
          f"({states['finished']} finished, {states['partial']} to resume, {states['new']} new)",
          file=stream)
    if not todo:
        return result
    backend.start()
    print(f"backend: {backend.describe()}", file=stream)
    target = comparison.episodes
    stop_at = comparison.base.stop_at
    if stop_at is not None:
        print(f"each run ends at its first evaluation at success {stop_at:g} (stop_at): the "
              f"bar's total and time are the most the runs can take; they shrink as runs end",
              file=stream)
    bar = tqdm(total=len(plans) * target, unit="ep", desc="compare", file=stream,
               disable=not progress, dynamic_ncols=True)
    ended: set[str] = set(result.skipped)
    logged: dict[str, int] = {}
    counted: set[str] = set()          # ended runs whose final count is in ``logged``

    def count() -> None:
        for p in plans:
            if p.name not in counted:  # an ended run's metrics.csv is read once, not every poll
                logged[p.name] = logged_episodes(p.path)
                if p.name in ended:
                    counted.add(p.name)
        bar.n, bar.total = episode_budget(logged, ended, target)

    queue = list(todo)
    try:
        count()
        bar.refresh()
        while queue or backend.running:
            while queue and backend.running < backend.capacity:
                backend.submit(task_for(comparison, queue.pop(0)))
            for outcome in backend.wait(poll_s):
                result.outcomes.append(outcome)
                if outcome.ok:
                    ended.add(outcome.name)
                tqdm.write(_describe(outcome), file=stream)
                if outcome.traceback:
                    tqdm.write(outcome.traceback.rstrip(), file=stream)
            count()
            bar.refresh()
    finally:
        bar.close()
        backend.close()
    return result


def compare(root: str | Path, request: CompareRequest, backend, poll_s: float = 2.0,
            progress: bool = True, stream=None) -> CompareResult:
    """``prepare`` the comparison in ``root`` and ``run_comparison`` it, holding its lock."""
    with DirectoryLock(root, "dualarm compare"):
        comparison = prepare(root, request)
        return run_comparison(comparison, backend, poll_s=poll_s, progress=progress, stream=stream)


def parse_conditions(text: str) -> tuple[str, ...]:
    """"none,multi" -> ("none", "multi") in canonical order; InputError names a bad one."""
    items = [c.strip() for c in text.split(",") if c.strip()]
    return _conditions(items, "--conditions")


def parse_seeds(text: str) -> tuple[int, ...]:
    """"0,1,2" -> (0, 1, 2); InputError if a seed is not an integer >= 0."""
    try:
        items = [int(s) for s in text.split(",") if s.strip()]
    except ValueError:
        raise InputError(f"--seeds: expected integers separated by commas, got {text!r}") from None
    return _seeds(items, "--seeds")

