"""The whole experiment in one call: demonstrations -> constraints -> comparison -> report.

What ``dualarm pipeline`` runs. Running it again resumes: the constraint files are
re-extracted (seconds, identical bytes), the comparison skips finished runs and resumes the
others, and the report is rewritten.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from dualarm.constraints.extraction import constraints_from_folder
from dualarm.experiments.compare import (CompareRequest, CompareResult, compare, load_manifest,
                                         merged_grid)
from dualarm.demos.formats import DEFAULT_DEMO_DIR, SCENE_NAME
from dualarm.experiments.report import save_report
from dualarm.experiments.summary import Report, build_report
from dualarm.task import DEMOS_CONDITION, TARGET_SUCCESS

#: (condition, segment spec) of the constraint files the comparison needs (paper: C1, C2&C3).
CONSTRAINT_SETS = (("single", "reach+grasp+align"), ("multi", "reach+grasp,align"))

#: The pipeline's grid when a new comparison's request leaves it open (the README's first
#: command): one seed per condition, under the recipe (the comparison's default base), for
#: long enough that every condition learns. The recipe's runs first reached 0.85 evaluation
#: success at 1,920-3,200 episodes in all 15 runs of its 3 x 5 comparison (seed 0: none 2,560,
#: single 3,200, multi 2,880), so 6,000 leaves room for another machine's
#: slower draw; the full reproduction is ``--episodes 10000 --seeds 0,1,2,3,4``.
DEFAULT_SEEDS = (0,)
DEFAULT_EPISODES = 6000
#: ... and each run ends at the evaluation that reaches the report's target: what the report
#: measures is there by then, and the four runs take about half the time (a run that never
#: gets there trains all its episodes).
DEFAULT_STOP_AT = TARGET_SUCCESS


def pipeline_request(output: str | os.PathLike, request: CompareRequest,
                     demo_dir: str | os.PathLike | None = None) -> CompareRequest:
    """``request`` with the pipeline's ``DEFAULT_SEEDS``, ``DEFAULT_EPISODES`` and
    ``DEFAULT_STOP_AT`` where it leaves them open, for a new comparison in ``output`` (the last
    two only without a ``base``, whose own count then, as in ``compare``); one that exists keeps its own
    (None there means "as in the manifest", and its episodes are never shortened).

    The demonstrations ``demo_dir`` (None: the shipped set) are also the recordings of the
    ``demos`` condition: it joins the paper's three in a new comparison where ``request``
    names no conditions and the folder has its scene file (without one, the recordings cannot
    be replayed), and wherever ``request`` names it.

    Raises:
        InputError: ``output`` holds an unreadable comparison manifest.
    """
    folder = Path(demo_dir) if demo_dir is not None else DEFAULT_DEMO_DIR
    new = load_manifest(output) is None
    named = request.conditions is not None and DEMOS_CONDITION in request.conditions
    by_default = new and request.conditions is None and (folder / SCENE_NAME).is_file()
    if (named or by_default) and request.demos_dir is None:
        request = replace(request, demos_dir=folder)
    if not new:
        return request
    episodes = request.episodes
    if episodes is None and request.base is None:     # a base config's own episodes stand
        episodes = DEFAULT_EPISODES
    return replace(request, seeds=request.seeds if request.seeds is not None else DEFAULT_SEEDS,
                   episodes=episodes,
                   stop_at=request.stop_at if request.stop_at is not None or request.base is not None
                   else DEFAULT_STOP_AT)


def planned_grid(output: str | os.PathLike,
                 request: CompareRequest) -> tuple[tuple[str, ...], tuple[int, ...]]:
    """The (conditions, seeds) the comparison in ``output`` will hold after ``request``
    (after ``pipeline_request``), as ``compare`` merges them (``merged_grid``)."""
    return merged_grid(load_manifest(output), request)


class PipelineStopped(Exception):
    """A step failed; ``step`` (1-based) and ``title`` name it, ``__cause__`` says why."""

    def __init__(self, step: int, title: str):
        super().__init__(f"pipeline stopped at step {step} ({title})")
        self.step, self.title = step, title


@dataclass(frozen=True)
class PipelineResult:
    """What a pipeline call did.

    Attributes:
        constraints: condition -> the constraints file written for it.
        comparison: the comparison step's result (its ``failed`` runs, if any).
        report: the report, or None when a run failed (the report step is not reached).
        report_index: its ``index.html``, or None.
    """

    constraints: dict[str, Path]
    comparison: CompareResult
    report: Report | None = None
    report_index: Path | None = None


def _stderr(line: str) -> None:
    print(line, file=sys.stderr)


def run_pipeline(output: str | os.PathLike, request: CompareRequest, backend,
                 demo_dir: str | os.PathLike | None = None, *, progress: bool = True,
                 log: Callable[[str], None] = _stderr) -> PipelineResult:
    """Extract C1 and C2&C3 from ``demo_dir``, train the comparison in ``output``, report it.

    Args:
        output: the comparison directory; constraints go to ``output/constraints``, the
            report to ``output/report``.
        request: the comparison's grid and settings (its ``constraints_dir`` is replaced by
            the extracted files).
        backend: a ``dualarm.experiments.backends`` backend (local workers or Ray).
        demo_dir: demonstrations with their labels; None for the shipped set.
        progress: progress bars for the extraction and the training.
        log: receives one line per step.
    Raises:
        PipelineStopped: from the error of the step that failed.
    """
    out = Path(output)
    request = pipeline_request(out, request, demo_dir)
    conditions, seeds = planned_grid(out, request)
    budget = request.episodes if request.episodes is not None else "the comparison's"
    titles = [f"constraints {name} ({spec}) from the demonstrations" for name, spec in CONSTRAINT_SETS]
    titles += [f"training: conditions {','.join(conditions)} x seeds {','.join(map(str, seeds))}, "
               f"{budget} episodes each",
               "report: Figs. 6-8, table, HTML"]
    step = 0

    def begin() -> str:
        nonlocal step
        step += 1
        log(f"[{step}/{len(titles)}] {titles[step - 1]}")
        return titles[step - 1]

    written: dict[str, Path] = {}
    try:
        for name, spec in CONSTRAINT_SETS:
            begin()
            path = out / "constraints" / f"{name}.yaml"
            constraints_from_folder(demo_dir, spec, name=name, progress=progress).save(path)
            written[name] = path
        begin()
        result = compare(out, replace(request, constraints_dir=out / "constraints"), backend,
                         progress=progress)
        if result.failed:
            return PipelineResult(written, result)
        begin()
        report = build_report(out)
        index = save_report(report, out / "report")
    except Exception as exc:        # not KeyboardInterrupt: an interrupted run resumes
        raise PipelineStopped(step, titles[step - 1]) from exc
    return PipelineResult(written, result, report, index)
