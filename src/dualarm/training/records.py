"""What a run records as it goes: a metrics.csv row per episode, an eval.csv row per
evaluation, the TensorBoard scalars beside them (``events/``), and where the time went."""

from __future__ import annotations

import time
from contextlib import contextmanager

import numpy as np

from dualarm.training.curriculum import START_CLASSES


def metrics_columns(vec, later_starts: bool) -> list[str]:
    """metrics.csv's columns for episodes of ``vec`` (its agents, sub-tasks and reward terms);
    with ``later_starts``, the sub-task each arm began at."""
    columns = ["episode", "env_steps", "wall_time_s", "steps"]
    columns += [f"return_{a}" for a in vec.agents] + ["return_total", "success"]
    if vec.has_subtasks:
        columns += [f"subtask_{a}" for a in vec.agents]
    if later_starts:
        columns += [f"start_{a}" for a in vec.agents]
    columns += [f"{t}_{a}" for t in vec.term_names for a in vec.agents]
    return columns


def episode_rows(vec, r, n: int, first_episode: int, env_steps_before: int, wall_s: float,
                 starts: np.ndarray | None) -> list[dict]:
    """metrics.csv rows of a round's first ``n`` episodes (``run_round``'s result ``r``),
    numbered from ``first_episode``; env_steps counts from ``env_steps_before`` the steps up to
    each episode's end in copy order; ``starts`` (n, A) the sub-task each arm began at, or None."""
    rows = []
    for i in range(n):
        row = {"episode": first_episode + i,
               "env_steps": env_steps_before + int(r.steps[:i + 1].sum()),
               "wall_time_s": f"{wall_s:.3f}", "steps": int(r.steps[i])}
        for k, name in enumerate(vec.agents):
            row[f"return_{name}"] = f"{r.returns[i, k]:.6f}"
        row["return_total"] = f"{r.returns[i].sum():.6f}"
        row["success"] = int(r.success[i])
        if vec.has_subtasks:
            for k, name in enumerate(vec.agents):
                row[f"subtask_{name}"] = int(r.subtask[i, k])
        if starts is not None:
            for k, name in enumerate(vec.agents):
                row[f"start_{name}"] = int(starts[i, k])
        for t in vec.term_names:
            for k, name in enumerate(vec.agents):
                row[f"{t}_{name}"] = f"{r.terms[t][i, k]:.6f}"
        rows.append(row)
    return rows


def eval_row(episodes: int, env_steps: int, wall_s: float, result, average=None) -> dict:
    """eval.csv's row of an evaluation ``result`` (and of the averaged actors', ``average``)."""
    row = {"episode": episodes, "env_steps": env_steps, "wall_time_s": f"{wall_s:.3f}",
           "success_rate": f"{result.success_rate:.4f}",
           "return_mean": f"{result.mean_return:.6f}", "steps_mean": f"{result.steps.mean():.3f}"}
    if average is not None:
        row["average_success_rate"] = f"{average.success_rate:.4f}"
        row["average_return_mean"] = f"{average.mean_return:.6f}"
    return row


def log_round(writer, rows: list[dict], losses: list[dict], recent_success, episodes: int,
              curriculum=None, action_l2: float | None = None) -> None:
    """A round's TensorBoard scalars: each episode's return and success, the mean of each loss
    over the round's updates, the success rate of the last 100 episodes, and the curriculum's
    frontier and success by start class."""
    for row in rows:
        writer.add_scalar("train/return_total", float(row["return_total"]), row["episode"])
        writer.add_scalar("train/success", row["success"], row["episode"])
    for key in dict.fromkeys(k for x in losses for k in x):
        writer.add_scalar(f"loss/{key}", float(np.mean([x[key] for x in losses if key in x])),
                          episodes)
    writer.add_scalar("train/success_rate_100", float(np.mean(recent_success)), episodes)
    if curriculum is not None:
        writer.add_scalar("curriculum/frontier", curriculum.frontier(), episodes)
        writer.add_scalar("train/action_l2", action_l2, episodes)
        for name, rate in zip(START_CLASSES, curriculum.success_rates()):
            if rate is not None:
                writer.add_scalar(f"curriculum/success_from_{name}", rate, episodes)


def log_evaluation(writer, result, episodes: int, average=None) -> None:
    """An evaluation's TensorBoard scalars."""
    if average is not None:
        writer.add_scalar("eval/average_success_rate", average.success_rate, episodes)
    writer.add_scalar("eval/success_rate", result.success_rate, episodes)
    writer.add_scalar("eval/return_mean", result.mean_return, episodes)


class Timing(dict):
    """Seconds by part of a round, and counts, since the process started training
    (``Trainer.timing``; ``benchmarks/train_speed.py`` reads it)."""

    @contextmanager
    def part(self, name: str):
        """Add the seconds the ``with`` block takes to ``self[name]``."""
        start = time.perf_counter()
        try:
            yield
        finally:
            self[name] += time.perf_counter() - start


def progress_postfix(recent_success, recent_return, last_eval: dict | None) -> dict:
    """The progress bar's figures: success and return over the last 100 episodes, and the
    last evaluation's success."""
    post = {"succ100": f"{np.mean(recent_success):.2f}", "ret100": f"{np.mean(recent_return):.1f}"}
    if last_eval is not None:
        post["eval"] = f"{last_eval['success_rate']:.2f}"
    return post
