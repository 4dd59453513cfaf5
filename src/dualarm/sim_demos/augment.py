"""More demonstrations than recordings: each recording's hand path moved with the objects it
acts on, replayed at new placements, the successes kept (after MimicGen, Mandlekar et al. 2023).

A recording's hands (``demonstration_path``) are split by its own labels into sub-task
segments, arm by arm. Each segment is expressed in the frame of the object it acts on, which
in this task only translates:

- **reach**: from the hand's start (the robot's home, the same in every scene) to its box. The
  path moves with the box by a share that grows linearly over the segment, from 0 at its start
  to the box's whole displacement at its end (MimicGen's interpolation from the current pose
  into the object-relative segment, folded into the segment itself).
- **grasp**: at the box: moved by the box's displacement.
- **align**: carrying the box to its target: moved by a share that passes linearly from the
  box's displacement to the target's. After the window: the target's.

The moved path is followed in the simulator at the new placement exactly as a recording is
(``follow_path``); the environment pays its own rewards and says whether it succeeded. Only
successes are kept. New placements come from the task's own random placements (the
environment's reset), so the demonstrations cover the distribution the learner is evaluated on.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dualarm.demos.labels import DemoLabels
from dualarm.demos.loading import DemoJoints
from dualarm.demos.scene import Scene
from dualarm.sim_demos.replay import (DEFAULT_STEPS, Replay, demonstration_path, follow_path,
                                      task_window)

#: Attempts per demonstration wanted before giving up: a yield below 1 / 8 means the
#: recordings do not carry to the task's placements.
MAX_ATTEMPTS_PER_EPISODE = 8


@dataclass
class Augmented:
    """What an augmentation produced.

    Attributes:
        replays: the successful replays, in the order found (each named after its recording).
        attempts: placements tried.
        sources: (attempts,) the recording each attempt moved.
        successes: (attempts,) bool, which attempts succeeded.
        placements: the placement of each successful replay (as ``replays``).
    """

    replays: list[Replay]
    attempts: int
    sources: list[str]
    successes: np.ndarray
    placements: list[Scene] = field(default_factory=list)

    @property
    def yield_(self) -> float:
        """Share of attempts that succeeded."""
        return float(self.successes.mean()) if self.attempts else 0.0


def segment_steps(labels: DemoLabels, steps: int) -> np.ndarray:
    """The labels' sub-task windows (2, 3, 2) in steps of the retimed task window (0 at its
    start, ``steps`` at its end; fractional), arm by arm, sub-task by sub-task, [start, end]."""
    start, end = task_window(labels)
    return (np.asarray(labels.windows, dtype=float) - start) / (end - start) * steps


def move_path(path: np.ndarray, windows: np.ndarray, source: Scene, target: Scene) -> np.ndarray:
    """``path`` (K + 1, 2, 3) m, recorded at ``source``, moved for the placement ``target``:
    each arm's reach, grasp and align segments (``windows`` (2, 3, 2) in steps, from
    ``segment_steps``) follow the box or the target they act on (module docstring).

    Returns:
        (K + 1, 2, 3) m.
    """
    k = np.arange(len(path), dtype=float)[:, None]                         # (K + 1, 1)
    box_shift = np.asarray(target.boxes, float) - np.asarray(source.boxes, float)
    box_shift[:, 2] = 0.0                 # boxes rest on the table: heights differ by rounding only
    target_shift = np.asarray(target.targets, float) - np.asarray(source.targets, float)

    def share(window):                   # (K + 1, 2): 0 before each arm's window, 1 after it
        lo, hi = window[:, 0], window[:, 1]
        return np.clip((k - lo) / np.maximum(hi - lo, 1e-9), 0.0, 1.0)

    to_box = share(windows[:, 0])                                          # over reach
    to_target = share(windows[:, 2])                                       # over align
    shift = (to_box[..., None] * box_shift
             + to_target[..., None] * (target_shift - box_shift))           # (K + 1, 2, 3)
    return np.asarray(path, float) + shift


def random_placement(env, seed: int) -> Scene:
    """One of the task's own random placements (``env``'s reset with ``seed``)."""
    env.reset(seed=seed)
    return Scene(boxes=env.box_start.copy(), targets=env.targets.copy())


def augment(env, demos: list[DemoJoints], labels: dict[str, DemoLabels],
            scenes: dict[str, Scene], episodes: int, seed: int,
            steps: int = DEFAULT_STEPS, on_attempt=None) -> Augmented:
    """Up to ``episodes`` successful demonstrations at new placements, from the recordings.

    Attempt j places the task at random with seed ``seed + j``, moves recording j mod n to it
    (``move_path``; taken in turn, every recording contributes alike: measured on the shipped
    set, any recording moved to any placement succeeds), and follows the moved path in ``env``
    (cartesian control). It stops at ``episodes`` successes or after
    ``MAX_ATTEMPTS_PER_EPISODE * episodes`` attempts.

    Args:
        demos: the recordings as Baxter joints with gripper events; their ``labels`` and
            ``scenes`` by name.
        on_attempt: called after each attempt with (attempts so far, successes so far).
    """
    if env.config.control != "cartesian":
        raise ValueError("augmentation follows hand paths in cartesian control")
    names = [d.name for d in demos]
    moving = {d.name: (demonstration_path(env, d, labels[d.name], steps),
                       segment_steps(labels[d.name], steps)) for d in demos}
    replays: list[Replay] = []
    sources: list[str] = []
    successes: list[bool] = []
    placements: list[Scene] = []
    for j in range(MAX_ATTEMPTS_PER_EPISODE * episodes):
        if len(replays) >= episodes:
            break
        placement = random_placement(env, seed + j)
        name = names[j % len(names)]
        (path, closed), windows = moving[name]
        moved = move_path(path, windows, scenes[name], placement)
        r = follow_path(env, name, moved, closed, placement)
        sources.append(name)
        successes.append(r.success)
        if r.success:
            replays.append(r)
            placements.append(placement)
        if on_attempt is not None:
            on_attempt(len(successes), len(replays))
    return Augmented(replays, len(successes), sources, np.asarray(successes, dtype=bool), placements)
