"""`dualarm report`: the run directories of a comparison -> Figs. 6-8, a table and an HTML page.

``dualarm.experiments.summary.build_report`` reads every run directory under a comparison
directory and summarises each condition over its seeds; this module writes it: ``write_report`` writes the figures, ``table.md``, ``table.csv`` and
``index.html``. The definitions (moving average, episodes to target, convergence, confidence
interval) are in ``dualarm.curves`` and docs/report.md.
"""

from __future__ import annotations

import csv
import html
import io
import math
from pathlib import Path

import numpy as np

from dualarm.atomic import atomic_open
from dualarm.experiments.findings import findings
from dualarm.curves import RATIO_PAIRS
from dualarm.experiments.summary import (QUANTITY_NAMES, RATIO_QUANTITIES, Report, SeedStat, build_report,
                                         paper_ratio, paper_value, ratio_note, relative_to_root)
from dualarm.task import CONDITION_NAMES, TARGET_SUCCESS


def _num(x: float | None, digits: int) -> str:
    return "" if x is None or not math.isfinite(x) else f"{x:.{digits}f}"


def _csv_num(x: float | None) -> str:
    return "" if x is None or not math.isfinite(x) else f"{x:.10g}"


_DIGITS = {"episodes_to_target": 0, "time_to_target_s": 0, "convergence_episode": 0,
           "convergence_time_s": 0,
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
              f"time to success {t:g}, s", "episodes to convergence", "time to convergence, s",
              "max average success", "final evaluation success", f"paper: to {TARGET_SUCCESS:g}", "paper: convergence",
              "paper: time, s", "paper: max success"]
    rows = []
    for c, s in report.conditions.items():
        paper = [paper_value(report, q, c) for q in ("episodes_to_target", "convergence_episode",
                                                      "convergence_time_s", "max_avg_success")]
        rows.append([
            CONDITION_NAMES[c] + f" ({c})", str(s.seeds),
            f"1-{s.episodes}" + (" (common range)" if s.truncated else ""),
            _cell(s.episodes_to_target, "episodes_to_target"),
            _cell(s.time_to_target_s, "time_to_target_s"),
            _cell(s.convergence_episode, "convergence_episode"),
            _cell(s.convergence_time_s, "convergence_time_s"),
            _cell(s.max_avg_success, "max_avg_success", count=False),
            _cell(s.final_eval_success, "final_eval_success", count=False),
            *("" if v is None else f"{v:g}" for v in paper)])
    return header, rows


def ratio_rows(report: Report) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the ratio table: quantity, ratio, ours (of the means), ours (of the
    medians, unreached seeds beyond the run, with its 95% bootstrap interval), the paper's,
    remarks."""
    header = ["quantity", "ratio", "this comparison (means)",
              "median ratio, 95% CI (unreached = beyond the run)", "paper", "remarks"]
    rows = []
    for q in RATIO_QUANTITIES:
        for pair in RATIO_PAIRS:
            ours = report.ratios[q][pair]
            paper, quoted = paper_ratio(q, pair)
            if q == "episodes_to_target" and not math.isclose(report.target, TARGET_SUCCESS):
                paper_text = f"({TARGET_SUCCESS:g} only)"
            elif paper is None:
                paper_text = "n/a"
            else:
                paper_text = f"{paper:.2f}" + ("" if quoted else " (derived)")
            note = ratio_note(report, q, pair)
            name = QUANTITY_NAMES[q] + (f" {report.target:g}" if q == "episodes_to_target" else "")
            rows.append([name, f"{pair[0]}/{pair[1]}",
                         "n/a" if ours is None else f"{ours:.2f}" + (" †" if note else ""),
                         _median_ratio_text(report.median_ratios[q][pair], pair[1]),
                         paper_text, note])
    return header, rows


def _ratio_num(x: float) -> str:
    # 0 only where the denominator's median is beyond the run (episodes are positive)
    return "beyond the run" if math.isinf(x) else "0" if x == 0 else f"{x:.2f}"


def _median_ratio_text(m: tuple[float, float, float] | None, denominator: str = "") -> str:
    """"1.32 (0.87 to beyond the run)"; "0 (none beyond the run) (0 to 0.41)" where the
    denominator condition's median never got there; "n/a" when not available."""
    if m is None:
        return "n/a"
    r, lo, hi = m
    text = _ratio_num(r)
    if r == 0 and denominator:
        text += f" ({denominator} beyond the run)"
    if not (math.isnan(lo) or math.isnan(hi)):
        text += f" ({_ratio_num(lo)} to {_ratio_num(hi)})"
    return text


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
                     relative_to_root(r.path, report.source), "; ".join(remarks)])
    return header, rows


def human_rows(report: Report) -> tuple[list[str], list[list[str]]]:
    """Per condition: the share of joint-steps inside the human ranges and the posture
    distance to the demonstrations at the same phase, means over the measured runs."""
    header = ["condition", "runs measured", "inside the human ranges of the sub-task",
              "posture distance to the demonstrations, rad"]
    rows = []
    for condition, measures in report.human.items():
        rows.append([condition, str(len(measures)),
                     f"{np.mean([m.inside for m in measures]):.3f}",
                     f"{np.mean([m.posture for m in measures]):.3f}"])
    return header, rows


def _human_caption(report: Report) -> str:
    return ("Each run's best policy, 10 deterministic episodes from the reset, every step of "
            "both arms, against the shipped demonstrations and their multi-segment ranges; "
            f"the demonstrations among themselves (each against the others): "
            f"{report.human_reference:.3f} rad.")


def csv_table(report: Report) -> str:
    """``table.csv``: one row per condition, plain numbers (empty = not available)."""
    cols = ["condition", "seeds", "episodes_compared", "target", "window"]
    for q in ("episodes_to_target", "time_to_target_s", "convergence_episode", "convergence_time_s"):
        cols += [f"{q}_mean", f"{q}_ci95", f"{q}_seeds_reached"]
    for q in ("max_avg_success", "final_eval_success"):
        cols += [f"{q}_mean", f"{q}_ci95", f"{q}_seeds"]
    cols += [f"paper_{q}" for q in ("episodes_to_target", "convergence_episode",
                                    "convergence_time_s", "max_avg_success")]
    for q in RATIO_QUANTITIES:
        for den in ("none", "single", "multi"):
            cols += [f"{q}_ratio_vs_{den}", f"{q}_median_ratio_vs_{den}",
                     f"{q}_median_ratio_vs_{den}_low", f"{q}_median_ratio_vs_{den}_high",
                     f"paper_{q}_ratio_vs_{den}"]
    text = io.StringIO()
    w = csv.writer(text, lineterminator="\n")
    w.writerow(cols)
    for c, s in report.conditions.items():
        row = [c, s.seeds, s.episodes, f"{report.target:g}", report.window]
        for q in ("episodes_to_target", "time_to_target_s", "convergence_episode",
                  "convergence_time_s", "max_avg_success", "final_eval_success"):
            st = s.stat(q)
            row += [_csv_num(st.mean), _csv_num(st.ci95), st.reached]
        row += [_csv_num(paper_value(report, q, c)) for q in (
            "episodes_to_target", "convergence_episode", "convergence_time_s", "max_avg_success")]
        for q in RATIO_QUANTITIES:
            for den in ("none", "single", "multi"):
                pair = (c, den)
                if pair in RATIO_PAIRS:
                    paper = paper_ratio(q, pair)[0]
                    if q == "episodes_to_target" and not math.isclose(report.target, TARGET_SUCCESS):
                        paper = None
                    med = report.median_ratios[q][pair] or (None,) * 3
                    row += [_csv_num(report.ratios[q][pair]),
                            *(("inf" if x is not None and math.isinf(x) else _csv_num(x)) for x in med),
                            _csv_num(paper)]
                else:
                    row += [""] * 5
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
        "Median ratios: the quotient of the two conditions' medians over all their seeds, a seed "
        "that never reached the criterion counted as beyond the run (so a condition's median "
        "is 'beyond the run' when half its seeds or more failed), with the 2.5-97.5 percentile "
        "interval of the same quotient over 10,000 bootstrap resamplings of each condition's "
        "seeds (fixed seed). It does not drop failed seeds, as the ratio of the means must.",
        "Time to success: the run's cumulative wall time (training, evaluations and checkpoints) "
        "at the episode of the target; wall times are of whatever machine and load the runs had.",
        "Runs of one condition with different lengths are compared over their common episode "
        "range (1 to the shortest run's length); the longer runs' later episodes are not used.",
    ]


FIGURES = {"fig6": "fig6_return.png", "fig7": "fig7_success.png", "fig8": "fig8_convergence_time.png"}


def _write_text(path: Path, text: str) -> None:
    with atomic_open(path) as f:
        f.write(text.encode())


def markdown(report: Report) -> str:
    """``table.md``: the per-condition table, the ratios, the notes and the definitions."""
    parts = [f"# Comparison report: {report.source}", "",
             f"Moving average over {report.window} episodes, success target {report.target:g}, "
             "mean ± 95% CI over seeds (k/n: seeds that reached the criterion).", ""]
    found = findings(report)
    if found:
        parts += ["## Findings", ""] + [f"- {line}" for line in found] + [""]
    parts += [_md_table(*summary_rows(report)), "", "## Ratios between conditions", "",
             _md_table(*ratio_rows(report))]
    if report.human:
        parts += ["", "## Human-likeness", "", _human_caption(report), "",
                  _md_table(*human_rows(report))]
    parts += ["", "## Runs", "", _md_table(*run_rows(report))]
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
            f"target {report.target:g}, mean ± 95% CI over seeds.</p>"]
    found = findings(report)
    if found:
        body += ["<h2>Findings</h2><ul>"] + [f"<li>{html.escape(x)}</li>" for x in found] + ["</ul>"]
    body += ["<h2>Summary</h2>", _html_table(*summary_rows(report)),
            "<h2>Ratios between conditions</h2>", _html_table(*ratio_rows(report))]
    if report.human:
        body += ["<h2>Human-likeness</h2>", f"<p>{html.escape(_human_caption(report))}</p>",
                 _html_table(*human_rows(report))]
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
    (created if missing), each atomically, index.html last; first the human-likeness of each
    run that has a policy (``human_likeness.measure_runs``). Returns the path of index.html."""
    from dualarm.experiments import report_plots
    from dualarm.experiments.human_likeness import measure_runs

    if not report.human:
        report.human, report.human_reference, notes = measure_runs(report.runs)
        report.notes.extend(notes)

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
                 target: float = TARGET_SUCCESS, actors: str = "policy") -> Path:
    """Write the report of a comparison directory: Figs. 6-8 (PNG), table.md, table.csv and
    index.html, each atomically, index.html last.

    Args:
        comparison_dir: directory holding the run directories (see ``build_report``).
        out: output directory (default: ``comparison_dir/report``).
        window: moving-average window, episodes, >= 1.
        target: success rate of "episodes to target", in (0, 1].
        actors: whose evaluations to read, "policy" or "average" (see ``build_report``).

    Returns:
        The path of index.html.

    Raises:
        InputError: no run directory, or a run directory with a missing column or a
            non-numeric value (the message names the file and the column).
    """
    report = build_report(comparison_dir, window, target, actors)
    return save_report(report, Path(out) if out is not None else Path(comparison_dir) / "report")
