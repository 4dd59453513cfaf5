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
from dualarm.experiments.compare import CompareRequest, CompareResult, compare
from dualarm.experiments.report import save_report
from dualarm.experiments.summary import Report, build_report
from dualarm.task import CONDITIONS

#: (condition, segment spec) of the constraint files the comparison needs (paper: C1, C2&C3).
CONSTRAINT_SETS = (("single", "reach+grasp+align"), ("multi", "reach+grasp,align"))


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
    conditions = request.conditions or CONDITIONS
    seeds = request.seeds or (0, 1, 2)
    titles = [f"constraints {name} ({spec}) from the demonstrations" for name, spec in CONSTRAINT_SETS]
    titles += [f"training: conditions {','.join(conditions)} x seeds {','.join(map(str, seeds))}, "
               f"{request.episodes if request.episodes is not None else 'default'} episodes each",
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
