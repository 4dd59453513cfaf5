"""Where a training episode begins: the start distribution, one object that the environment
draws each arm's first sub-task from (as robosuite injects one placement sampler).

A later sub-task's start is either placed by the simulator (inverse kinematics puts the grip
at the box, or the box part of the way to its target) or, with ``RecordedStates``, taken from
a successful demonstration episode at a step where that arm was at that sub-task: a state a
robot reaches by replaying the demonstration (Salimans and Chen 2018 started episodes from a
demonstration's states; Florensa et al. 2017's reverse curriculum from placed ones).

Evaluations use ``NORMAL_START``: every arm at home, the task's normal reset.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from dualarm.errors import InputError


@dataclass(frozen=True)
class RecordedStates:
    """Per-arm states of E successful demonstration episodes, step by step, to start from.

    Attributes:
        boxes: (E, 2, 3) m, each episode's box start positions (rows left, right).
        targets: (E, 2, 3) m, each episode's targets.
        qpos: (E, K, 2, 16) each arm's joints (7, rad), fingers (2, m), box position (3, m) and
            orientation (4, w x y z), after the reset (step 0) and after each step; K is the
            longest episode's steps + 1.
        fingers: (E, K, 2, 2) each arm's finger commands, m.
        subtask: (E, K, 2) int, each arm's sub-task at that step (0 reach, 1 grasp, 2 align);
            -1 past the episode's end.
    """

    boxes: np.ndarray = field(repr=False)
    targets: np.ndarray = field(repr=False)
    qpos: np.ndarray = field(repr=False)
    fingers: np.ndarray = field(repr=False)
    subtask: np.ndarray = field(repr=False)

    def __post_init__(self):
        e, k = self.subtask.shape[:2]
        shapes = {"boxes": (e, 2, 3), "targets": (e, 2, 3), "qpos": (e, k, 2, 16),
                  "fingers": (e, k, 2, 2), "subtask": (e, k, 2)}
        for name, shape in shapes.items():
            if np.shape(getattr(self, name)) != shape:
                raise ValueError(f"RecordedStates.{name}: shape {np.shape(getattr(self, name))}, "
                                 f"expected {shape}")
        if e == 0:
            raise ValueError("RecordedStates: no episodes")
        for cls in range(3):
            if not (self.subtask == cls).any(axis=1).all():
                raise ValueError(f"RecordedStates: an episode has an arm that never was at "
                                 f"sub-task {cls} (only successful episodes pass through all)")

    @classmethod
    def from_episodes(cls, episodes) -> "RecordedStates":
        """Stack episodes, each a mapping with ``boxes``, ``targets`` (2, 3) and ``qpos``
        (S + 1, 2, 16), ``fingers`` (S + 1, 2, 2), ``subtask`` (S + 1, 2) of its own length."""
        k = max(len(ep["subtask"]) for ep in episodes)

        def pad(key, fill):
            out = []
            for ep in episodes:
                a = np.asarray(ep[key])
                extra = np.full((k - len(a),) + a.shape[1:], fill, dtype=a.dtype)
                out.append(np.concatenate([a, extra]))
            return np.stack(out)

        return cls(np.stack([np.asarray(ep["boxes"], float) for ep in episodes]),
                   np.stack([np.asarray(ep["targets"], float) for ep in episodes]),
                   pad("qpos", 0.0), pad("fingers", 0.0), pad("subtask", -1).astype(np.int64))

    def __len__(self) -> int:
        return len(self.boxes)

    def draw(self, rng: np.random.Generator, starts: np.ndarray, approach: bool) -> tuple[int, np.ndarray]:
        """An episode e and each arm's step (2,): a uniform step of e at which that arm was at
        its ``starts`` sub-task; an arm at reach begins at step 0 (home) unless ``approach``."""
        e = int(rng.integers(len(self)))
        steps = np.zeros(2, dtype=np.int64)
        for arm, cls in enumerate(np.asarray(starts)):
            if cls == 0 and not approach:
                continue
            steps[arm] = rng.choice(np.flatnonzero(self.subtask[e, :, arm] == cls))
        return e, steps


@dataclass(frozen=True)
class StartDistribution:
    """Per-arm probabilities of beginning an episode at each sub-task, and where reach starts
    begin.

    Attributes:
        probs: (reach, grasp, align), 3 non-negative numbers summing to 1: at home (reach),
            at its box with the fingers open (grasp done is still to do), or holding its box
            part of the way to its target (align). Drawn per arm, after the placement.
        approach: an arm that starts at reach begins a uniform fraction of the way from home
            to just above its box (gripper down, fingers open) instead of at home: starts that
            cover the approach, so that the value of being at the box can spread back along it.
        states: None: later starts are placed by the simulator. Otherwise an episode in which
            some arm draws a later sub-task begins at one of these demonstration episodes'
            scenes, each arm at a uniform step of it where that arm was at its drawn sub-task
            (with ``approach``, an arm at reach at a uniform step of its reach; else at home);
            an episode in which both arms draw reach is the normal reset at a random placement.
    """

    probs: tuple[float, float, float] = (1.0, 0.0, 0.0)
    approach: bool = False
    states: RecordedStates | None = field(default=None, compare=False, repr=False)

    def __post_init__(self):
        p = np.asarray(self.probs, dtype=float)
        if p.shape != (3,) or not np.isfinite(p).all() or (p < 0).any() or abs(p.sum() - 1) > 1e-6:
            raise InputError("probs: start probabilities must be 3 non-negative numbers (reach, "
                             f"grasp, align) that sum to 1, got {list(np.ravel(p))}")
        object.__setattr__(self, "probs", tuple(float(x) for x in p))

    @property
    def later(self) -> bool:
        """Whether an arm may begin past reach."""
        return self.probs[0] != 1.0

    def with_probs(self, probs) -> "StartDistribution":
        """The same distribution with other probabilities (a curriculum's move)."""
        return replace(self, probs=tuple(probs))

    def with_states(self, states: RecordedStates | None) -> "StartDistribution":
        """The same distribution with its later starts taken from ``states``."""
        return replace(self, states=states)

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        """(2,) int: the sub-task each arm begins at (0 reach, 1 grasp, 2 align). The normal
        reset draws nothing from ``rng``, so its episodes are those of a task without starts."""
        if not self.later:
            return np.zeros(2, dtype=np.int64)
        p = np.asarray(self.probs)
        return rng.choice(3, size=2, p=p / p.sum())


#: Every arm at home: evaluations, and the paper's training.
NORMAL_START = StartDistribution()
