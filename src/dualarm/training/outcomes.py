"""Where each arm's episode ends up: one outcome per arm and episode, named by the link of
the task (reach, grasp, carry) at which it stopped.

``link_outcomes`` runs seeded episodes of a deterministic policy on the Baxter task and
classes each arm's episode by what its observations show, exactly one class per arm (the
box never grasped in all but the first three):

``aligned``                its box at its target at the end (the arm's part of a success);
``held, not at target``    holding its box at the end, away from the target;
``dropped``                grasped its box at some step, not at the end;
``slid out of the grip``   after the reach, the fingers closed within the grasp tolerance of
                           the box and it rose, but it never counted as grasped (it slipped);
``closed, not lifted``     after the reach, the fingers closed within the grasp tolerance of
                           the box; it never rose by ``lift_height``;
``closed off the box``     after the reach, the fingers first closed farther than the grasp
                           tolerance from the box (a grip that drifted off while closing);
``reached, not closed``    came within reach of its box, never closed the fingers;
``closed, not reached``    never within reach, moving, and the fingers closed within
                           ``near_radius`` of the box (with nothing between them: a hand
                           closed early cannot take the box);
``moved, not reached``     never within reach, moving, never within ``near_radius`` of the box
                           with the fingers closed (most often: never near the box at all);
``still``                  never within reach, its mean motion command under ``still_action``.

A learner that fails shows here which link fails and how: an arm that keeps still at home,
a grip that drifts off the box while the fingers close, a grip too weak to lift. "Closed" is
the task's own test (finger gap at most the box width plus ``grasp_gap_margin``), so fingers
closed above the box, with nothing between them, count as closed too. The report also
keeps each unreached arm's closest approach to its box: an arm that never comes near is a
failure of the approach, not of the grip.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualarm.envs.rules import closed_gap, finger_gap, observation_layout
from dualarm.envs.config import TaskConfig
from dualarm.task import ARMS
from dualarm.training.evaluation import evaluate
from dualarm.training.vector import EVAL_SEED_BASE, VectorEnv

#: Outcome classes, from the end of the task back to its start.
OUTCOMES = ("aligned", "held, not at target", "dropped", "slid out of the grip",
            "closed, not lifted", "closed off the box", "reached, not closed",
            "closed, not reached", "moved, not reached", "still")


@dataclass
class OutcomeReport:
    """Outcome counts of ``link_outcomes``.

    Attributes:
        counts: (A, len(OUTCOMES)) int, episodes per arm and outcome (each row sums to
            ``episodes``).
        success: (episodes,) bool, the task solved.
        episodes: how many episodes.
        closest_unreached: per arm, the closest approach (m) of its box in each episode in
            which it never reached it.
        held_away: per arm, its box's distance (m) from its target at the end of each episode
            in which it ended ``held, not at target``: just over ``align_threshold`` is a
            carry that fell short, tens of centimetres one that never carried.
    """

    counts: np.ndarray
    success: np.ndarray
    episodes: int
    closest_unreached: tuple[list[float], list[float]] = ([], [])
    held_away: tuple[list[float], list[float]] = ([], [])

    @property
    def success_rate(self) -> float:
        return float(self.success.mean()) if self.episodes else float("nan")

    def share(self, arm: int, outcome: str) -> float:
        """Fraction of the episodes in which ``arm`` (0 left, 1 right) had ``outcome``."""
        return float(self.counts[arm, OUTCOMES.index(outcome)] / max(self.episodes, 1))

    def table(self) -> str:
        """The counts as aligned text: one line per outcome that occurred, one column per arm."""
        lines = [f"  {'outcome':<24}" + "".join(f"{arm:>8}" for arm in ARMS)]
        for k, name in enumerate(OUTCOMES):
            if self.counts[:, k].any():
                lines.append(f"  {name:<24}" + "".join(f"{int(n):>8}" for n in self.counts[:, k]))
        for label, per_arm in (("not reached: closest, cm", self.closest_unreached),
                               ("held: from target, cm", self.held_away)):
            if any(per_arm):
                medians = [f"{100 * np.median(d):>8.1f}" if d else f"{'-':>8}" for d in per_arm]
                lines.append(f"  {label:<24}" + "".join(medians) + "  (median)")
        return "\n".join(lines)


class _ArmTrace:
    """Running per-arm facts of the episodes in n copies: (n, A) arrays."""

    def __init__(self, n: int):
        shape = (n, 2)
        self.reached = np.zeros(shape, dtype=bool)
        self.grasped_ever = np.zeros(shape, dtype=bool)
        self.closed_at = np.full(shape, np.nan)     # grip-to-box distance (m) when the fingers
        #                                             first count as closed after the reach
        self.lifted_closed = np.zeros(shape, dtype=bool)
        self.closed_unreached = np.zeros(shape, dtype=bool)   # closed near the box, before any reach
        self.closest = np.full(shape, np.inf)       # closest approach of the box so far, m
        self.motion = np.zeros(shape)               # summed mean |motion command|
        self.steps = np.zeros(n, dtype=np.int64)
        self.box_rest_z = np.full(shape, np.nan)    # the box's height at the first step, m


def _classify(t: _ArmTrace, i: int, last_obs: np.ndarray, last_subtask: np.ndarray,
              layout: dict, task: TaskConfig, still_action: float) -> list[int]:
    """Outcome index per arm of copy ``i``'s finished episode."""
    out = []
    for arm in range(2):
        o = last_obs[arm]
        held = last_subtask[arm] == 2
        at_target = np.linalg.norm(o[layout["target_pos"]] - o[layout["object_pos"]]) < task.align_threshold
        if held and at_target:
            name = "aligned"
        elif held:
            name = "held, not at target"
        elif t.grasped_ever[i, arm]:
            name = "dropped"
        elif not t.reached[i, arm]:
            if t.motion[i, arm] / max(t.steps[i], 1) < still_action:
                name = "still"
            else:
                name = "closed, not reached" if t.closed_unreached[i, arm] else "moved, not reached"
        elif np.isnan(t.closed_at[i, arm]):
            name = "reached, not closed"
        elif t.closed_at[i, arm] >= task.grasp_tolerance:
            name = "closed off the box"
        elif t.lifted_closed[i, arm]:
            name = "slid out of the grip"
        else:
            name = "closed, not lifted"
        out.append(OUTCOMES.index(name))
    return out


def link_outcomes(act, vec: VectorEnv, task: TaskConfig, episodes: int = 32,
                  seed_base: int = EVAL_SEED_BASE, still_action: float = 0.05,
                  near_radius: float = 0.05) -> OutcomeReport:
    """Class each arm's episode of a deterministic policy by the link at which it stopped.

    Args:
        act: maps observations (n, A, O) to actions (n, A, U) in [-1, 1] (cartesian
            control: U = 4, (dx, dy, dz, grip)).
        vec: copies of the Baxter task (``BaxterVector``), e.g. from ``make_vector_env`` with
            ``start`` for episodes that begin at a later sub-task.
        task: the copies' task configuration (observation layout, thresholds).
        episodes: how many seeded episodes (the evaluation's seeds by default).
        still_action: mean |motion command| (per component, in [0, 1]) under which an arm
            that never reached its box counts as ``still``.
        near_radius: metres; fingers closed this near the box before the reach make an
            unreached arm ``closed, not reached``.
    """
    if not vec.has_subtasks:
        raise ValueError("link_outcomes needs the Baxter task's copies (sub-task states)")
    layout = observation_layout(task.observes_joint_angles)
    gap_closed = closed_gap(task)
    counts = np.zeros((2, len(OUTCOMES)), dtype=np.int64)
    closest, held_away = ([], []), ([], [])
    held_class = OUTCOMES.index("held, not at target")
    trace = _ArmTrace(vec.num_envs)

    def on_step(obs, actions, step, live):
        nonlocal trace
        o = step.obs[live]                                           # (m, A, O)
        first = trace.steps[live] == 0
        if first.any():                                              # a new episode in a copy
            fresh = _ArmTrace(1)
            for name, value in vars(fresh).items():
                getattr(trace, name)[live[first]] = value[0]
            trace.box_rest_z[live[first]] = obs[live[first]][..., layout["object_pos"]][..., 2]
        dist = np.linalg.norm(o[..., layout["object_rel_pos"]], axis=-1)    # (m, A)
        closed = finger_gap(o[..., layout["fingers"]]) <= gap_closed
        rise = o[..., layout["object_pos"]][..., 2] - trace.box_rest_z[live]
        sub = step.subtask[live]
        trace.reached[live] |= (sub >= 1) | (dist < task.reach_threshold)
        trace.closed_unreached[live] |= closed & ~trace.reached[live] & (dist <= near_radius)
        trace.closest[live] = np.minimum(trace.closest[live], dist)
        trace.grasped_ever[live] |= sub == 2
        newly = closed & trace.reached[live] & np.isnan(trace.closed_at[live])
        trace.closed_at[live] = np.where(newly, dist, trace.closed_at[live])
        trace.lifted_closed[live] |= closed & (rise >= task.lift_height)
        trace.motion[live] += np.abs(actions[live][..., :3]).mean(axis=-1)
        trace.steps[live] += 1
        for j, i in enumerate(live):
            if step.terminated[i] or step.truncated[i]:
                for arm, k in enumerate(_classify(trace, i, o[j], sub[j], layout, task, still_action)):
                    counts[arm, k] += 1
                    if not trace.reached[i, arm]:
                        closest[arm].append(float(trace.closest[i, arm]))
                    if k == held_class:
                        away = o[j, arm, layout["target_pos"]] - o[j, arm, layout["object_pos"]]
                        held_away[arm].append(float(np.linalg.norm(away)))
                trace.steps[i] = 0                                   # the copy's next episode

    result = evaluate(act, vec, episodes, seed_base, on_step=on_step)
    return OutcomeReport(counts, result.success, episodes, closest, held_away)
