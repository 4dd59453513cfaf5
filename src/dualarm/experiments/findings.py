"""What a comparison found, in words: the report's first lines.

A reader of ``dualarm pipeline`` or ``dualarm report`` first wants the answer to the paper's
question (did joint-angle guidance make the learner reach the success target in fewer
episodes?), and how much the answer is worth: with one seed per condition a ratio is one
draw of a noisy quantity, with several it comes with the seed-bootstrap interval of the
median ratio (``Report.median_ratios``). ``findings`` writes those sentences from the same
numbers the tables show.
"""

from __future__ import annotations

import math

import numpy as np

from dualarm.experiments.summary import Report, paper_ratio
from dualarm.task import TARGET_SUCCESS

#: The comparisons stated, in the order a reader asks them (guided against unguided first).
FINDING_PAIRS = (("multi", "none"), ("single", "none"), ("multi", "single"),
                 ("demos", "none"), ("demos", "multi"))

#: Seeds per condition below which a ratio is reported as a single draw, not a measurement.
MIN_SEEDS_FOR_INTERVAL = 2


def _episodes(x: float) -> str:
    return f"{x:,.0f}"


def _reached_line(report: Report) -> str:
    """Which conditions reached the target, and at what median episode."""
    t = report.target
    parts, missing = [], []
    for c, s in report.conditions.items():
        st = s.episodes_to_target
        if st.reached == 0:
            missing.append(f"{c} (0 of {st.seeds} seeds in {s.episodes:,} episodes)")
            continue
        # over all seeds, an unreached one beyond the run, as Report.median_ratios counts it
        med = float(np.median(np.where(np.isnan(st.values), np.inf, st.values)))
        where = (f"at {_episodes(med)} episodes" if st.seeds == 1 else
                 f"median {_median_text(med)} episodes, {st.reached} of {st.seeds} seeds")
        parts.append(f"{c} {where}")
    if not parts:
        return f"No condition reached success {t:g}: " + "; ".join(missing) + "."
    head = ("Every condition reached success" if not missing else "Reached success") + f" {t:g}: "
    line = head + "; ".join(parts) + "."
    if missing:
        line += " Not reached: " + "; ".join(missing) + "."
    return line


def _median_text(x: float) -> str:
    return "beyond the run" if math.isinf(x) else _episodes(x)


def _ratio_line(report: Report, pair: tuple[str, str]) -> str | None:
    """One sentence on ``pair``'s episodes-to-target ratio, or None when not available."""
    a, b = pair
    if a not in report.conditions or b not in report.conditions:
        return None
    m = report.median_ratios["episodes_to_target"].get(pair)
    if m is None:
        return f"{a}/{b}: neither reached success {report.target:g}, no ratio."
    ratio, low, high = m
    paper = None
    if math.isclose(report.target, TARGET_SUCCESS):
        paper = paper_ratio("episodes_to_target", pair)[0]
    paper_text = f" (paper: {paper:.2f})" if paper is not None else ""
    if math.isinf(ratio) or ratio == 0:
        slower = a if math.isinf(ratio) else b
        return (f"{a}/{b}: {slower} did not reach success {report.target:g} in most seeds"
                f"{paper_text}.")
    if round(ratio, 2) == 1:
        how = f"{a} needed as many episodes as {b}"
    else:
        how = (f"{a} needed {abs(1 - ratio):.0%} {'fewer' if ratio < 1 else 'more'} episodes "
               f"than {b}")
    text = f"{a}/{b} {ratio:.2f}: {how}{paper_text}"
    seeds = min(report.conditions[a].seeds, report.conditions[b].seeds)
    if seeds < MIN_SEEDS_FOR_INTERVAL or math.isnan(low) or math.isnan(high):
        return text + "; one seed each, a single draw rather than a measurement of the effect."
    what = "demonstrations" if a == "demos" else "guidance"
    if high < 1:
        verdict = f"{what} faster at 95 % ({low:.2f} to {high:.2f})"
    elif low > 1:
        verdict = f"{what} slower at 95 % ({low:.2f} to {high:.2f})"
    else:
        verdict = (f"95 % interval {low:.2f} to "
                   f"{'beyond the run' if math.isinf(high) else f'{high:.2f}'}, which includes "
                   "1: no difference measurable with these seeds")
    return f"{text}; {verdict}."


def findings(report: Report) -> list[str]:
    """The report's opening sentences: which conditions reached the success target and
    when, then the episodes-to-target ratios of ``FINDING_PAIRS`` (median ratio over seeds,
    unreached seeds beyond the run) against the paper's, with what the seeds allow one to
    say about them. Empty for a report without conditions."""
    if not report.conditions:
        return []
    lines = [_reached_line(report)]
    lines += [line for pair in FINDING_PAIRS if (line := _ratio_line(report, pair)) is not None]
    if min(s.seeds for s in report.conditions.values()) < MIN_SEEDS_FOR_INTERVAL:
        lines.append("More seeds per condition would measure it: --seeds 0,1,2,3,4 adds them "
                     "to the comparison (`dualarm pipeline` or `dualarm compare`; finished runs "
                     "are kept).")
    return lines
