"""The groups of a training config, one concern each: where episodes start (``starts``), what
the replay makes of the stored steps (``replay``), the potential-based shaping (``shaping``),
what changes near the box (``near_box``) and the demonstrations (``demos``). Each group checks
its own values in one place and travels whole; checks that join two groups are
``TrainConfig``'s. The defaults are the recipe's; ``OFF`` is the paper's (nothing beyond it).
How each value was found and what it measured: docs/learning-runs.md.
"""

from __future__ import annotations

from dataclasses import dataclass

from dualarm.envs.starts import StartDistribution
from dualarm.errors import InputError
from dualarm.typed_fields import Settings, check_field_types


def _at_least_zero(group, *names: str) -> None:
    for name in names:
        if getattr(group, name) < 0:
            raise InputError(f"{name} must be >= 0, got {getattr(group, name)}")


def _share(group, *names: str) -> None:
    for name in names:
        if not 0 <= getattr(group, name) <= 1:
            raise InputError(f"{name} must be in [0, 1], got {getattr(group, name)}")


@dataclass(frozen=True)
class Starts(Settings):
    """Where training episodes begin; evaluations always start from the normal reset.

    Attributes:
        probs: probabilities (reach, grasp, align) with which each arm begins a training
            episode at that sub-task: at its box with the fingers open, or holding its box part
            of the way to its target (Andrychowicz et al. 2017 started pick-and-place episodes
            with the box in the gripper). (1, 0, 0): every episode starts normally, as in the
            paper.
        curriculum: 0 keeps ``probs`` fixed. Otherwise a reverse curriculum
            (``dualarm.training.curriculum``) moves the starts backwards as the task is learned:
            the sub-task at which most arms start (with the largest of ``probs``) begins at
            align and moves one sub-task earlier once the episodes starting later succeed at
            this rate.
        probe: with ``curriculum``: at every evaluation, this many episodes of the deterministic
            policy with both arms starting at each later sub-task (at the boxes, holding them)
            measure the curriculum's success rates, the way evaluations measure success; 0
            measures them on the training episodes, whose exploration can hold a learned class
            below the threshold for good.
        approach: an arm that starts at reach begins a uniform fraction of the way from home to
            just above its box instead of at home: starts that cover the approach to the box.
    """

    LABEL = "starts"

    probs: tuple[float, float, float] = (0.2, 0.2, 0.6)
    curriculum: float = 0.5
    probe: int = 32
    approach: bool = True

    def __post_init__(self):
        check_field_types(self)
        object.__setattr__(self, "probs", self.distribution().probs)   # checks them
        _share(self, "curriculum")
        _at_least_zero(self, "probe")
        for name in ("curriculum", "approach"):
            if getattr(self, name) and not self.later:
                raise InputError(f"{name} moves the start states: give probs other than "
                                 "(1, 0, 0), for example [0.2, 0.2, 0.6]")
        if self.probe and not self.curriculum:
            raise InputError("probe measures the curriculum's success rates: give curriculum too")

    @property
    def later(self) -> bool:
        """Whether training episodes may start beyond the normal reset."""
        return tuple(self.probs) != (1.0, 0.0, 0.0)

    def distribution(self) -> StartDistribution:
        """The environment's start distribution of the training episodes."""
        return StartDistribution(self.probs, self.approach)


@dataclass(frozen=True)
class Replay(Settings):
    """What the replay makes of the stored steps (the environment supplies the goal, reward and
    mirror functions; ``dualarm.training.storage`` applies them).

    Attributes:
        her_share: share of every replay batch whose goals are replaced by what the arms
            achieved later in the same episode, rewards recomputed (hindsight experience replay,
            Andrychowicz et al. 2017, "future" goals): the targets by where the boxes went, or,
            in the reach task (``task.success_at: reach``), the boxes by where the grip sites
            went. 0 turns it off.
        recombine_share: share of every replay batch whose right arm's half (observation,
            action, reward, next observation) is taken from another row of the batch, the
            coordination bonus and the episode's end computed again for the joined step: the
            arms and their boxes never touch, so the halves of two steps make a third the robot
            could have taken (counterfactual data augmentation, Pitis et al. 2020). Full task
            only. 0: rows as stored.
        mirror: store every training episode twice, as it happened and as its mirror image
            (``dualarm.envs.mirror``: the scene reflected left to right, the arms swapped, the
            guide term recomputed for the arm the joints then belong to), so each arm's agent
            learns from the other arm's experience as well (Kaleidoscope Experience Replay, Lin
            et al. 2020). Episode counts and logged returns are the real episodes'. Needs the
            joint angles in the observation in a guided condition.
    """

    LABEL = "replay"

    her_share: float = 0.8
    recombine_share: float = 1.0
    mirror: bool = True

    def __post_init__(self):
        check_field_types(self)
        _share(self, "her_share", "recombine_share")


@dataclass(frozen=True)
class Shaping(Settings):
    """Potential-based shaping of each arm's learner reward (Ng, Harada and Russell 1999): the
    term gamma * phi(s') - phi(s) leaves the optimal policies of the paper's reward unchanged,
    and the logged returns are the paper's.

    Attributes:
        approach: k, in the learner's reward units per metre, with phi(s) = -k * (the distance
            from the arm's grip site to its box), phi = 0 after a success: a gradient towards
            the box where the task's value is still out of sight (the reach from home). 0: off.
        carry: k, with phi(s) = -k * (the distance from the arm's box to its target): the same
            gradient for the carry, where the paper's distance term, scaled with rc to 1, is
            4,000 times weaker. The box rests until grasped, so before the grasp the term is the
            constant -(1 - gamma) phi. Both potentials add. 0: off.
    """

    LABEL = "shaping"

    approach: float = 1.0
    carry: float = 1.0

    def __post_init__(self):
        check_field_types(self)
        _at_least_zero(self, "approach", "carry")


@dataclass(frozen=True)
class NearBox(Settings):
    """What the learner does differently within ``radius`` of its box (the observation's
    box-minus-grip offset) and beyond it.

    Attributes:
        radius: metres.
        far_action_l2: the weight of the action penalty beyond ``radius``; ``algo.action_l2``
            applies within it. The penalty steadies the grasp and the carry, near the box; far
            from it, it holds the arm still at home. None: ``algo.action_l2`` everywhere.
        random_eps: the share of uniformly random exploring actions within ``radius``;
            ``algo.random_eps`` applies beyond it. Random steps of up to a full action knock a
            closing grip off its box. None: ``algo.random_eps`` everywhere.
    """

    LABEL = "near_box"

    radius: float = 0.05
    far_action_l2: float | None = 0.002
    random_eps: float | None = 0.0

    def __post_init__(self):
        check_field_types(self)
        if self.radius <= 0:
            raise InputError(f"radius must be > 0, got {self.radius}")
        if self.far_action_l2 is not None:
            _at_least_zero(self, "far_action_l2")
        if self.random_eps is not None:
            _share(self, "random_eps")


@dataclass(frozen=True)
class Demos(Settings):
    """The demonstration buffer that ``algo.demo_batch_size`` and ``algo.bc_weight`` draw from.

    Attributes:
        folder: a demonstration folder (recordings with gripper events, labels.csv and
            scene.csv) whose recordings, replayed at their own scenes in the run's task
            (``dualarm.sim_demos.replay``), fill the buffer, beside ``episodes`` of them moved
            to the task's random placements (MimicGen). A replay that does not succeed is left
            out and named. In a file, a relative path is relative to the file's folder; a file
            may give the folder alone (``demos: DIR``). None: no recordings, as in the paper.
        episodes: demonstration episodes recorded before training: with ``folder``, the moved
            recordings (0 there means ``DEMOS_EPISODES``); without it, of the scripted expert
            (cartesian control only). 0 for none, as in the paper's three conditions.
        shuffle: a control for ``folder``: each demonstration episode's actions are permuted in
            time before they are stored (the same steps and actions, each paired with another
            step's state), so the demonstrations keep their action statistics but lose what the
            person did where. A speed-up that survives it does not come from the motion.
        starts: with ``folder``: training episodes that start an arm at a later sub-task begin
            at a state of one of the successful demonstration episodes, where that arm was at
            that sub-task (``dualarm.envs.starts.RecordedStates``), instead of a state placed by
            the simulator: states a robot reaches by replaying the demonstration. Needs
            ``starts.probs`` other than (1, 0, 0); the curriculum's probes start there too.
        buffer: with ``folder``: the successful replays' transitions fill the demonstration
            buffer (drawn as ``DEMOS_ALGO`` says). False: the recordings are used as start
            states alone (needs ``starts``), the control that tells the two uses apart.

    The recordings' hand paths are followed one retimed point per step, at the person's pace
    (``dualarm.sim_demos.replay.follow_path``).
    """

    LABEL = "demos"
    #: Following by phase (arc length from where the grip site is, at the robot's pace) and
    #: the demonstrations copied into the replay measured no gain and left the code
    #: (docs/learning-runs.md).
    REMOVED = {"following": "time", "in_replay": False}

    folder: str | None = None
    episodes: int = 0
    shuffle: bool = False
    starts: bool = False
    buffer: bool = True

    @classmethod
    def from_dict(cls, d, where: str = "config", base=None):
        return super().from_dict(folder_as_mapping(d), where, base)

    def __post_init__(self):
        check_field_types(self)
        _at_least_zero(self, "episodes")
        if self.shuffle and self.folder is None:
            raise InputError("shuffle is a control for the recordings: give folder too")
        if self.starts and self.folder is None:
            raise InputError("starts begins episodes at the recordings' replayed states: give "
                             "folder too (on the command line, --demos DIR)")
        if not self.buffer and not self.starts:
            raise InputError("buffer: false leaves the recordings unused unless they give the "
                             "start states: set starts: true too")

    @property
    def recordings(self) -> bool:
        """Whether people's recordings are the demonstrations."""
        return self.folder is not None


#: The groups of a TrainConfig, by field name.
GROUPS = {"starts": Starts, "replay": Replay, "shaping": Shaping, "near_box": NearBox,
          "demos": Demos}

#: The paper's value of each group: nothing beyond the paper's DDPG.
OFF = {"starts": Starts(probs=(1.0, 0.0, 0.0), curriculum=0.0, probe=0, approach=False),
       "replay": Replay(her_share=0.0, recombine_share=0.0, mirror=False),
       "shaping": Shaping(approach=0.0, carry=0.0),
       "near_box": NearBox(far_action_l2=None, random_eps=None),
       "demos": Demos()}

#: Where each option of the flat layout (run directories and files written before the groups)
#: lives now: old name -> (group, field).
FLAT_FIELDS = {"start_probs": ("starts", "probs"), "start_curriculum": ("starts", "curriculum"),
               "curriculum_probe": ("starts", "probe"), "approach_starts": ("starts", "approach"),
               "her_share": ("replay", "her_share"),
               "recombine_share": ("replay", "recombine_share"),
               "mirror_episodes": ("replay", "mirror"),
               "approach_shaping": ("shaping", "approach"), "carry_shaping": ("shaping", "carry"),
               "near_box_radius": ("near_box", "radius"),
               "far_action_l2": ("near_box", "far_action_l2"),
               "near_random_eps": ("near_box", "random_eps"),
               "demo_episodes": ("demos", "episodes"), "shuffle_demos": ("demos", "shuffle"),
               "demo_following": ("demos", "following")}     # a removed option: only "time"


def folder_as_mapping(value):
    """``demos`` as a mapping: a bare folder (or None) is short for ``{folder: value}``."""
    return {"folder": value} if value is None or isinstance(value, str) else value


def nest_flat_fields(d: dict, where: str) -> dict:
    """``d`` (one layer of training settings) with its flat-layout options moved into their
    groups, and a bare ``demos: DIR`` as ``demos: {folder: DIR}``; a group given both ways names
    both."""
    d = dict(d)
    if "demos" in d:
        d["demos"] = folder_as_mapping(d["demos"])
    for old, (group, name) in FLAT_FIELDS.items():
        if old not in d:
            continue
        value = d.pop(old)
        section = d.get(group, {})
        if not isinstance(section, dict):
            raise InputError(f"{where}: {group}: expected a mapping of {group} settings, "
                             f"got {section!r}"[:160])
        if name in section:
            raise InputError(f"{where}: give {group}.{name} or its old name {old}, not both")
        d[group] = {**section, name: value}
    return d
