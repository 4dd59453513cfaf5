"""How human-like a learned policy moves (issue 45): measured on its deterministic episodes
against the demonstrations, per arm and step.

- **Inside share**: the share of joint-steps inside the human ranges of the arm's current
  sub-task (a constraint set, Eq. 12; by default the shipped multi-segment one), in [0, 1].
- **Posture distance**: at each step, the RMS over the arm's 7 joints of its distance to the
  nearest demonstration at the same *phase* (rad). The phase is the arm's sub-task plus the
  fraction of that sub-task done: in a demonstration from its labels, in an episode from the
  steps the arm spent in that sub-task. A policy that moves as the people did scores near
  the spread among the people themselves.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dualarm.task import SUBTASKS

#: Phase samples per sub-task of each demonstration.
PHASE_POINTS = 21


@dataclass(frozen=True)
class DemoPostures:
    """The demonstrations' postures by phase: ``q`` (D, 2, 3, PHASE_POINTS, 7) rad, recording d,
    arm (left, right), sub-task, phase sample 0 (sub-task start) .. 1 (its end), joint."""

    q: np.ndarray

    @classmethod
    def from_recordings(cls, demos, labels) -> "DemoPostures":
        """From recordings as Baxter joints (``DemoJoints``) and their labels by name."""
        at = np.linspace(0.0, 1.0, PHASE_POINTS)
        out = np.empty((len(demos), 2, len(SUBTASKS), PHASE_POINTS, 7))
        for d, demo in enumerate(demos):
            windows = np.asarray(labels[demo.name].windows, dtype=float)   # (2, 3, 2) s
            for arm in range(2):
                for k in range(len(SUBTASKS)):
                    start, end = windows[arm, k]
                    times = start + at * (end - start)
                    for j in range(7):
                        out[d, arm, k, :, j] = np.interp(times, demo.time, demo.q[:, 7 * arm + j])
        return cls(out)

    @classmethod
    def from_folder(cls, demo_dir: str | Path) -> "DemoPostures":
        """From a demonstration folder (recordings and labels.csv)."""
        from dualarm.demos.loading import load_demo_dir

        demos, labels = load_demo_dir(demo_dir)
        return cls.from_recordings(demos, labels)


def episode_phases(subtasks: np.ndarray) -> np.ndarray:
    """Each step's phase fraction (T, 2) in [0, 1] within the arm's current sub-task, from the
    sub-tasks (T, 2) after each step: the steps of each run of one sub-task share it evenly."""
    subtasks = np.asarray(subtasks)
    out = np.zeros(subtasks.shape, dtype=float)
    for arm in range(subtasks.shape[1]):
        s = subtasks[:, arm]
        start = 0
        for t in range(1, len(s) + 1):
            if t == len(s) or s[t] != s[start]:
                n = t - start
                out[start:t, arm] = (np.arange(n) + 1) / n
                start = t
    return out


def posture_distance(q: np.ndarray, subtasks: np.ndarray, postures: DemoPostures) -> float:
    """Mean over steps and arms of the RMS joint distance (rad) of the posture ``q`` (T, 14)
    to the nearest demonstration at the same phase (``subtasks`` (T, 2) after each step)."""
    q = np.asarray(q, dtype=float)
    phase = episode_phases(subtasks)
    index = np.rint(phase * (PHASE_POINTS - 1)).astype(int)                # (T, 2)
    distances = []
    for arm in range(2):
        demo = postures.q[:, arm, np.asarray(subtasks)[:, arm], index[:, arm]]   # (D, T, 7)
        rms = np.sqrt(((demo - q[None, :, 7 * arm:7 * arm + 7]) ** 2).mean(-1))  # (D, T)
        distances.append(rms.min(axis=0))
    return float(np.mean(distances))


def inside_share(q: np.ndarray, subtasks: np.ndarray, constraints) -> float:
    """Share of joint-steps of ``q`` (T, 14) inside ``constraints``' ranges of each arm's
    current sub-task (``subtasks`` (T, 2))."""
    s = np.asarray(subtasks)
    return float(constraints.inside(q, s[:, 0], s[:, 1]).mean())


@dataclass(frozen=True)
class HumanLikeness:
    """A policy's human-likeness over its episodes: ``inside`` share in [0, 1],
    ``posture`` distance (rad), ``episodes`` measured."""

    inside: float
    posture: float
    episodes: int


def policy_human_likeness(run: str | Path, postures: DemoPostures, constraints,
                          episodes: int = 10, seed: int = 0) -> HumanLikeness:
    """Both measures on ``episodes`` deterministic episodes of a run's best policy, from
    ``reset(seed + k)`` (every step of each episode, success or not)."""
    from dualarm.envs.rollout import run_episode
    from dualarm.training.policy import policy_env

    _, env, policy, _ = policy_env(Path(run), "best")
    inside, posture = [], []
    try:
        for k in range(episodes):
            e = run_episode(env, policy, seed + k)
            q = e.joint_angles[1:]                    # the posture after each step
            inside.append(inside_share(q, e.subtasks, constraints))
            posture.append(posture_distance(q, e.subtasks, postures))
    finally:
        env.close()
    return HumanLikeness(float(np.mean(inside)), float(np.mean(posture)), episodes)


def demonstrations_among_themselves(postures: DemoPostures, demos, labels) -> float:
    """The posture distance of each demonstration to the others (leave one out), averaged:
    the spread among the people, the scale a policy's distance is read against (rad)."""
    out = []
    for i, demo in enumerate(demos):
        others = DemoPostures(np.delete(postures.q, i, axis=0))
        windows = np.asarray(labels[demo.name].windows, dtype=float)
        sub = np.full((len(demo.time), 2), -1)
        for arm in range(2):
            for k in range(len(SUBTASKS)):
                sub[(demo.time >= windows[arm, k, 0]) & (demo.time <= windows[arm, k, 1]), arm] = k
        keep = (sub >= 0).all(axis=1)
        out.append(posture_distance(demo.q[keep], sub[keep], others))
    return float(np.mean(out))


def measure_runs(runs, episodes: int = 10) -> tuple[dict[str, list[HumanLikeness]], float | None, list[str]]:
    """Both measures for every run with a policy checkpoint (``Run`` of the report), against
    the shipped demonstrations and their multi-segment constraints.

    Returns:
        condition -> the runs' measures; the demonstrations' own spread (rad, or None when no
        run was measured); notes on runs left out.
    """
    from dualarm.constraints.constraint_set import ConstraintSet, default_constraints_path
    from dualarm.demos.formats import DEFAULT_DEMO_DIR
    from dualarm.demos.loading import load_demo_dir
    from dualarm.errors import DualarmError
    from dualarm.training.run_dir import RunPaths

    with_policy = [r for r in runs if RunPaths(r.path).best.exists() or RunPaths(r.path).latest.exists()]
    if not with_policy:
        return {}, None, []
    demos, labels = load_demo_dir(DEFAULT_DEMO_DIR)
    postures = DemoPostures.from_recordings(demos, labels)
    constraints = ConstraintSet.load(default_constraints_path("multi"))
    out: dict[str, list[HumanLikeness]] = {}
    notes = []
    for r in with_policy:
        try:
            out.setdefault(r.condition, []).append(
                policy_human_likeness(r.path, postures, constraints, episodes))
        except (DualarmError, ValueError, RuntimeError) as exc:
            notes.append(f"{r.path}: human-likeness not measured ({exc})")
    return out, demonstrations_among_themselves(postures, demos, labels), notes
