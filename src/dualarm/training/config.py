"""Everything a training run is made of, in one typed value saved as ``config.yaml``.

``TrainConfig()`` is **the recipe**: the settings under which DADDPG learns the whole task
without demonstrations, in every condition (how each was found and what it measured:
docs/learning-runs.md). ``TrainConfig.paper()`` is the paper's plain DDPG, the reproduction's
baseline (``--config paper``), which does not learn the full task.
"""

from __future__ import annotations

import functools
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import yaml

from dualarm.errors import InputError
from dualarm.rl.config import REMOVED_FIELDS as ALGO_REMOVED_FIELDS
from dualarm.rl.config import DADDPGConfig
from dualarm.task import MAX_SEED
from dualarm.typed_fields import check_field_types, drop_removed_fields
from dualarm.yaml_io import read_yaml

#: TaskConfig fields a run may override (the rest keep the task's defaults).
TASK_OVERRIDES = ("control", "goal", "success_at", "max_episode_steps", "joint_angles_in_obs",
                  "reach_threshold", "terminate_on_success", "coordinate_bonus", "grasp_bonus",
                  "reach_bonus", "guide_c0", "reach_funnel", "reach_funnel_height")

#: Options removed from TrainConfig, with the one value a file may still give (old run
#: directories keep loading); docs/learning-runs.md names the commit that had each and what
#: it measured.
REMOVED_FIELDS = {"reach_action_l2": None, "calm_radius": None, "approach_spread": 0.0,
                  "held_spread": 0.0, "grasp_spread": 0.0, "grasp_shaping": 0.0,
                  "early_close_shaping": 0.0, "her_goal_jitter": 0.0, "reward_heads": False}

#: The recipe's learner: DADDPGConfig's own defaults are plain DDPG (the paper's), with these
#: changes. Each value's reason is in docs/learning-runs.md.
RECIPE_ALGO = DADDPGConfig(
    hidden=(128, 128),         # 4x cheaper than 2 x 256 at no measured loss
    updates_per_step=0.25,     # half of it learned later; double, no sooner
    reward_scale=0.00025,      # 1 / rc: values in [0, 1], the shaping terms a tie-breaker
    action_l2=0.02,            # within 5 cm of the box and while holding it (far_action_l2 beyond)
    q_clip=1.0,                # targets within the reachable range (HER's clip_return)
    random_eps=0.3,            # HER's share of uniformly random actions, farther than 5 cm
    twin_critics=True,         # TD3's twin critics and target smoothing (Fujimoto et al. 2018)
    target_noise=0.2,
    twin_min_weight=0.5,       # WD3: the twin targets halfway from their minimum to their mean
    policy_average=0.001,      # averaged actors: an exponential average over ~1,000 updates ...
    eval_actor="average",      # ... which are the run's policy (training acts with the online ones)
)


#: The learner's use of demonstrations when ``demos`` is given to a config that draws none:
#: rows per update from the demonstration buffer, and the weight of Q-filtered behaviour
#: cloning (Nair et al. 2018) in the actor's loss, on the recipe's value scale (rc = 1).
DEMOS_ALGO = {"demo_batch_size": 64, "bc_weight": 1.0}
#: ... and the demonstration episodes made from the recordings by moving them to new
#: placements (``demo_episodes``): 64 scripted-expert episodes were too few, 256 enough.
DEMOS_EPISODES = 256


def _recipe_task() -> dict:
    return {"joint_angles_in_obs": True}     # every condition observes the joint angles


@functools.cache
def _task_field_defaults() -> dict:
    """TaskConfig's own value of each of its fields with a plain default."""
    from dualarm.envs.config import TaskConfig

    return {f.name: f.default for f in fields(TaskConfig)}


def _task_defaults(names) -> dict:
    """TaskConfig's own values of the fields ``names``: ``to_dict`` writes them for the keys
    the recipe's task sets, so that a file's ``task`` merged onto the recipe's (``from_dict``)
    gives back the same config."""
    return {name: value for name, value in _task_field_defaults().items() if name in names}


def _is_task_default(name: str, value) -> bool:
    default = _task_field_defaults().get(name, object())
    if isinstance(value, list):
        value = tuple(value)
    return type(value) is type(default) and value == default    # 1 is not True: checked later


@dataclass(frozen=True)
class TrainConfig:
    """A training run of DADDPG on the Baxter task. The defaults are the recipe (the
    learner's in ``RECIPE_ALGO``); ``TrainConfig.paper()`` turns every option beyond the paper
    off. Options below that the recipe leaves off were measured and not adopted
    (docs/learning-runs.md, "Tried and not adopted").

    Attributes:
        condition: "none", "single" or "multi" (paper Section 3.2.2).
        constraints: constraint file for "single"/"multi"; None uses the shipped default.
            In a config file, a relative path is relative to the file's folder.
        task: TaskConfig fields to override, by name (see ``TASK_OVERRIDES``).
        episodes: training episodes in all (a resumed run may raise it).
        seed: seeds the networks, the noise, the replay sampling and the episodes.
        num_envs: environment copies stepped together (policy inference is batched).
        eval_every: training episodes between evaluations (0: none).
        eval_episodes: evaluation episodes, deterministic policy, a fixed set of seeds.
        checkpoint_every: training episodes between checkpoints (0: only by time and at the end).
        checkpoint_minutes: wall-clock minutes between checkpoints.
        torch_threads: PyTorch intra-op threads (1 gives bit-reproducible runs).
        start_probs: probabilities (reach, grasp, align) with which each arm begins a
            training episode at that sub-task: at its box with the fingers open, or holding
            its box part of the way to its target (Andrychowicz et al. 2017 started
            pick-and-place episodes with the box in the gripper). Evaluations always start
            from the normal reset. (1, 0, 0): every episode starts normally, as in the paper.
        start_curriculum: 0 keeps ``start_probs`` fixed. Otherwise a reverse curriculum
            (``dualarm.training.curriculum``) moves the starts backwards as the task is
            learned: the sub-task at which most arms start (with the largest of
            ``start_probs``) begins at align and moves one sub-task earlier once the
            episodes starting later succeed at this rate (in training, with exploration noise,
            unless ``curriculum_probe``).
        curriculum_probe: with ``start_curriculum``: at every evaluation, this many episodes of
            the deterministic policy with both arms starting at each later sub-task (at the
            boxes, holding them) measure the curriculum's success rates, the way evaluations
            measure success; 0 measures them on the training episodes, whose exploration
            (noise, random actions) can hold a learned class below the threshold for good.
        far_action_l2: the weight of the action penalty for an arm whose grip site is more
            than ``near_box_radius`` from its box (the observation's box-minus-grip offset);
            ``algo.action_l2`` applies within it. The penalty steadies the grasp and the
            carry, near the box; far from it, it holds the arm still at home
            (docs/learning-runs.md). None: ``algo.action_l2`` everywhere.
        near_random_eps: ``algo.random_eps`` (the share of uniformly random exploring
            actions) for an arm whose grip site is within ``near_box_radius`` of its box;
            farther away ``algo.random_eps`` applies. Random steps of up to a full action
            knock a closing grip off its box (docs/learning-runs.md). None:
            ``algo.random_eps`` everywhere.
        near_box_radius: metres; see ``far_action_l2`` and ``near_random_eps``.
        approach_starts: an arm that starts a training episode at reach begins a uniform
            fraction of the way from home to just above its box instead of at home (needs
            ``start_probs``): training starts that cover the approach to the box.
        her_share: share of every replay batch whose goals are replaced by what the arms
            achieved later in the same episode, rewards recomputed (hindsight experience
            replay, Andrychowicz et al. 2017, "future" goals): the targets by where the
            boxes went, or, in the reach task (``task.success_at: reach``), the boxes by
            where the grip sites went. 0 turns it off.
        recombine_share: share of every replay batch whose right arm's half (observation,
            action, reward, next observation) is taken from another row of the batch, the
            coordination bonus and the episode's end computed again for the joined step: the
            arms and their boxes never touch, so the halves of two steps make a third the
            robot could have taken (counterfactual data augmentation, Pitis et al. 2020), and
            an arm's success is no longer paid only in episodes where the other arm
            succeeded at the same time. 0: rows as stored.
        approach_shaping: k, in the learner's reward units per metre: each arm's learner
            reward gains the potential-based term gamma * phi(s') - phi(s) with phi(s) = -k *
            (the distance from its grip site to its box), phi = 0 after a success (Ng, Harada
            and Russell 1999). A potential-based term leaves the optimal policies of the
            paper's reward unchanged and the logged returns are the paper's; it gives the
            critic a gradient towards the box where the task's value is still out of sight
            (the reach from home, docs/learning-runs.md). 0 turns it off.
        carry_shaping: k, as ``approach_shaping``'s but with phi(s) = -k * (the distance from
            each arm's box to its target): the same gradient for the carry, where the paper's
            distance term, scaled with rc to 1, is 4,000 times weaker. The box
            rests until grasped, so before the grasp the term is the constant -(1 - gamma) phi.
            Both potentials add. 0 turns it off.
        mirror_episodes: store every training episode twice, as it happened and as its mirror
            image (``dualarm.envs.mirror``: the scene reflected left to right, the arms
            swapped, the guide term recomputed for the arm the joints then belong to), so
            that each arm's agent learns from the other arm's experience as well (Kaleidoscope
            Experience Replay, Lin et al. 2020). Episode counts and logged returns are the
            real episodes'. Needs the joint angles in the observation in a guided condition.
        demo_episodes: episodes recorded into a demonstration buffer before training (used
            by ``algo.demo_batch_size`` and ``algo.bc_weight``): without ``demos``, of the
            scripted expert; with ``demos``, the recordings moved to the task's random
            placements (``dualarm.sim_demos.augment``, MimicGen), beside the recordings at their
            own scenes (0 there means ``DEMOS_EPISODES``). 0 for none, as in the paper's three
            conditions. The scripted expert demonstrates cartesian control only; the
            recordings serve either control.
        demos: a demonstration folder (recordings with gripper events, labels.csv and
            scene.csv) whose recordings, replayed at their own scenes in the run's task
            (``dualarm.sim_demos.replay``), fill the demonstration buffer that
            ``algo.demo_batch_size`` and ``algo.bc_weight`` draw from (where the algo draws no
            demonstration rows, ``DEMOS_ALGO``'s values), with ``DEMOS_EPISODES`` moved
            recordings unless ``demo_episodes`` says how many. A replay that does not succeed
            is left out and named. None: no recordings, as in the paper.
        shuffle_demos: a control for ``demos``: each demonstration episode's actions are
            permuted in time before they are stored (the same steps and the same actions,
            each paired with another step's state), so the demonstrations keep their action
            statistics but lose what the person did where. A speed-up that survives it does
            not come from the demonstrated motion.
        demo_following: how ``demos``' hand paths are followed in the simulator:
            "time", one retimed point per step at the person's pace
            (``dualarm.sim_demos.replay.follow_path``), or "phase", by arc length from where
            the grip site is, at the robot's pace (``track_path``): the action then depends on
            the state alone, as a policy's does.
        algo: the DADDPG hyper-parameters.
    """

    condition: str = "multi"
    constraints: str | None = None
    task: dict = field(default_factory=_recipe_task)
    episodes: int = 10000
    seed: int = 0
    num_envs: int = 16
    eval_every: int = 160
    eval_episodes: int = 50
    checkpoint_every: int = 0
    checkpoint_minutes: float = 2.0
    torch_threads: int = 1
    start_probs: tuple[float, float, float] = (0.2, 0.2, 0.6)
    start_curriculum: float = 0.5
    curriculum_probe: int = 32
    far_action_l2: float | None = 0.002
    near_random_eps: float | None = 0.0
    near_box_radius: float = 0.05
    approach_starts: bool = True
    her_share: float = 0.8
    recombine_share: float = 1.0
    approach_shaping: float = 1.0
    carry_shaping: float = 1.0
    mirror_episodes: bool = True
    demo_episodes: int = 0
    demos: str | None = None
    shuffle_demos: bool = False
    demo_following: str = "time"
    algo: DADDPGConfig = RECIPE_ALGO

    def __post_init__(self):
        check_field_types(self)
        from dualarm.task import CONDITIONS
        if self.condition not in CONDITIONS:
            raise InputError(f"condition must be one of {CONDITIONS}, got {self.condition!r}")
        unknown = sorted(set(self.task) - set(TASK_OVERRIDES), key=str)
        if unknown:
            raise InputError(f"task overrides {unknown} are not supported; allowed: {TASK_OVERRIDES}")
        if self.demos is not None and self.algo.demo_batch_size == 0:   # demos drawn as DEMOS_ALGO
            object.__setattr__(self, "algo", self.algo.with_(**DEMOS_ALGO))
        if self.demos is not None:        # whatever the algo says: the recordings are moved
            object.__setattr__(self, "demo_episodes", self.demo_episodes or DEMOS_EPISODES)
        # an override that gives the task's own default is no override: one config, one value
        object.__setattr__(self, "task", {k: v for k, v in self.task.items()
                                          if not _is_task_default(k, v)})
        for name in ("episodes", "num_envs", "torch_threads"):
            if getattr(self, name) < 1:
                raise InputError(f"{name} must be at least 1, got {getattr(self, name)}")
        if not 0 <= self.seed <= MAX_SEED:
            raise InputError(f"seed must be in 0..{MAX_SEED}, got {self.seed}")
        for name in ("eval_every", "eval_episodes", "checkpoint_every", "demo_episodes"):
            if getattr(self, name) < 0:
                raise InputError(f"{name} must be >= 0, got {getattr(self, name)}")
        try:
            task = self.task_config()
        except InputError as exc:
            raise InputError(f"task: {exc}") from None
        if self.algo.demo_batch_size > 0 and self.demo_episodes == 0 and self.demos is None:
            raise InputError("algo.demo_batch_size > 0 draws from demonstrations: set demos (a "
                             "demonstration folder) or demo_episodes")
        if self.demos is not None:
            from dualarm.sim_demos.replay import DEFAULT_STEPS
            if task.max_episode_steps < DEFAULT_STEPS:
                raise InputError(f"demos: a recording is retimed to {DEFAULT_STEPS} steps, longer "
                                 f"than task.max_episode_steps {task.max_episode_steps}")
        from dualarm.sim_demos.replay import FOLLOWING
        if self.demo_following not in FOLLOWING:
            raise InputError(f"demo_following must be one of {FOLLOWING}, got "
                             f"{self.demo_following!r}")
        if self.shuffle_demos and self.demos is None:
            raise InputError("shuffle_demos is a control for demos: give demos too")
        if self.demo_episodes and self.demos is None and task.control != "cartesian":
            raise InputError("demo_episodes: the scripted expert demonstrates cartesian control "
                             "only, not task.control 'joint'")
        from dualarm.envs.baxter import check_start_probs
        try:
            check_start_probs(self.start_probs)
        except ValueError as exc:
            raise InputError(f"start_probs: {exc}") from None
        if not 0 <= self.start_curriculum <= 1:
            raise InputError(f"start_curriculum must be in [0, 1], got {self.start_curriculum}")
        if self.curriculum_probe < 0:
            raise InputError(f"curriculum_probe must be >= 0, got {self.curriculum_probe}")
        if self.curriculum_probe and not (self.start_curriculum and self.eval_every):
            raise InputError("curriculum_probe measures the start_curriculum at every evaluation: "
                             "give start_curriculum and eval_every too")
        if self.far_action_l2 is not None and self.far_action_l2 < 0:
            raise InputError(f"far_action_l2 must be >= 0, got {self.far_action_l2}")
        if self.near_random_eps is not None and not 0 <= self.near_random_eps <= 1:
            raise InputError(f"near_random_eps must be in [0, 1], got {self.near_random_eps}")
        if self.near_box_radius <= 0:
            raise InputError(f"near_box_radius must be > 0, got {self.near_box_radius}")
        for name in ("start_curriculum", "approach_starts"):
            if getattr(self, name) and not self.uses_start_states:
                raise InputError(f"{name} moves the start states: give start_probs other "
                                 "than (1, 0, 0), for example [0.2, 0.2, 0.6]")
        for name in ("approach_shaping", "carry_shaping"):
            if getattr(self, name) < 0:
                raise InputError(f"{name} must be >= 0, got {getattr(self, name)}")
        if not 0 <= self.her_share <= 1:
            raise InputError(f"her_share must be in [0, 1], got {self.her_share}")
        if not 0 <= self.recombine_share <= 1 or (self.recombine_share > 0 and
                                                  self.task_config().success_at == "reach"):
            raise InputError(f"recombine_share must be in [0, 1] and works on the full task, "
                             f"got {self.recombine_share}")
        if self.checkpoint_minutes <= 0:
            raise InputError(f"checkpoint_minutes must be > 0, got {self.checkpoint_minutes}")
        if self.mirror_episodes and self.condition != "none" and not task.observes_joint_angles:
            raise InputError("mirror_episodes in a guided condition needs the joint angles in the "
                             "observation (task: {joint_angles_in_obs: true}): the mirrored guide "
                             "term is computed from them")

    def baxter_only_options(self) -> list[str]:
        """The options set in this config that exist for the Baxter task only (a custom
        PettingZoo environment has no scripted expert, start states, targets or reward terms)."""
        used = {"start_probs": self.uses_start_states, "her_share": self.her_share > 0,
                "demo_episodes": self.demo_episodes > 0,
                "demos": self.demos is not None,
                "far_action_l2": self.far_action_l2 is not None,
                "near_random_eps": self.near_random_eps is not None,
                "approach_shaping": self.approach_shaping > 0,
                "carry_shaping": self.carry_shaping > 0,
                "recombine_share": self.recombine_share > 0,
                "mirror_episodes": self.mirror_episodes}
        return [name for name, on in used.items() if on]

    @property
    def compared_condition(self) -> str:
        """The run's condition in a comparison: ``DEMOS_CONDITION`` with recordings as
        demonstrations, else ``condition``."""
        from dualarm.task import DEMOS_CONDITION

        return DEMOS_CONDITION if self.demos is not None else self.condition

    @property
    def uses_start_states(self) -> bool:
        """Whether training episodes may start beyond the normal reset."""
        return tuple(self.start_probs) != (1.0, 0.0, 0.0)

    def task_config(self):
        """The resolved ``TaskConfig`` of this run."""
        from dualarm.envs.config import TaskConfig

        return TaskConfig(condition=self.condition, **self.task)

    def constraints_file(self) -> Path | None:
        """The constraints file the guide term reads: ``constraints``, or the shipped file
        of the condition; None for "none"."""
        if self.condition == "none":
            return None
        from dualarm.constraints.constraint_set import default_constraints_path

        return Path(self.constraints or default_constraints_path(self.condition))

    def load_constraints(self):
        """The ``ConstraintSet`` of the guide term (None for "none")."""
        path = self.constraints_file()
        if path is None:
            return None
        from dualarm.constraints.constraint_set import ConstraintSet

        constraints = ConstraintSet.load(path)
        if self.condition == "single" and len(constraints.segments) != 1:
            raise InputError(f"{path}: condition 'single' needs one segment for the whole task, "
                             f"this file has {len(constraints.segments)} (use it with --condition multi)")
        return constraints

    def with_(self, **changes) -> "TrainConfig":
        """A copy with some fields changed (checked as a new config is)."""
        return replace(self, **changes)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["algo"] = self.algo.to_dict()
        d["start_probs"] = [float(p) for p in self.start_probs]
        task = {**_task_defaults(_recipe_task()), **self.task}    # every key the recipe sets
        d["task"] = {k: list(v) if isinstance(v, tuple) else v for k, v in task.items()}
        return d

    @classmethod
    def from_dict(cls, d: dict, where: str = "config", base: "TrainConfig | None" = None
                  ) -> "TrainConfig":
        """The config of a mapping of fields on top of ``base`` (default: the recipe): a field
        it gives replaces the base's, but ``algo`` and ``task`` are merged key by key, so a
        file says only what it changes. A run's own ``config.yaml`` is read on the paper's
        base instead (``load_saved``)."""
        base = cls() if base is None else base
        known = {f.name for f in fields(cls)}
        if not isinstance(d, dict):
            raise InputError(f"{where}: expected a mapping of training settings")
        d = drop_removed_fields(d, REMOVED_FIELDS, where)
        unknown = sorted(set(d) - known, key=str)
        if unknown:
            raise InputError(f"{where}: unknown field(s) {unknown}; known: {sorted(known)}")
        base_fields = base.to_dict()
        d = {**base_fields, **d}
        if isinstance(d["task"], dict):
            d["task"] = {**base_fields["task"], **d["task"]}
        d["algo"] = DADDPGConfig.from_dict(d["algo"] or {}, where=f"{where}: algo", base=base.algo)
        try:
            return cls(**d)
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from None

    def save(self, path: str | Path) -> None:
        from dualarm.atomic import atomic_open

        with atomic_open(path) as f:
            f.write(yaml.safe_dump(self.to_dict(), sort_keys=False).encode())

    @classmethod
    def recipe(cls) -> "TrainConfig":
        """The recipe, ``TrainConfig()``: the settings under which the paper's learner learns
        reach-grasp-align from the normal reset, the same for every condition (change
        ``condition``, ``seed`` and ``episodes`` with ``with_``)."""
        return cls()

    @classmethod
    def paper(cls) -> "TrainConfig":
        """The paper's plain DDPG (Section 2.3): one critic per agent, every episode from the
        normal reset, the paper's reward alone, 3,000 episodes; the joint angles observed in
        the guided conditions only. The reproduction's baseline; it does not learn the full
        task (docs/learning-runs.md)."""
        return cls(episodes=3000, eval_every=100, task={}, start_probs=(1.0, 0.0, 0.0),
                   start_curriculum=0.0, curriculum_probe=0, far_action_l2=None,
                   near_random_eps=None, approach_starts=False, her_share=0.0,
                   recombine_share=0.0, approach_shaping=0.0, carry_shaping=0.0,
                   mirror_episodes=False, algo=DADDPGConfig())

    @classmethod
    def preset(cls, name: str) -> "TrainConfig":
        """A named preset: ``recipe`` or ``paper`` (``PRESETS``)."""
        if name not in PRESETS:
            raise InputError(f"no preset {name!r}; the presets are {PRESETS}")
        return cls.paper() if name == "paper" else cls.recipe()

    @classmethod
    def load(cls, path: str | Path, changes: dict | None = None) -> "TrainConfig":
        """The config of a YAML file of fields, on top of the recipe; ``extends: BASE`` in it
        starts from another file's fields or a preset's (see :func:`read_config_layers`).
        ``path`` may also be a preset's name (``recipe``, ``paper``). ``changes`` (fields, as
        the command line gives them) replace the file's before the whole is checked."""
        changes = changes or {}
        if not Path(path).exists():
            if str(path) in PRESETS:
                return cls.from_dict(changes, where=str(path), base=cls.preset(str(path)))
            raise InputError(f"{path}: no such config file; give a YAML file of settings or a "
                             f"preset ({', '.join(PRESETS)})")
        d, base = read_config_layers(Path(path))
        return cls.from_dict({**d, **changes}, where=str(path), base=cls.preset(base))

    @classmethod
    def load_saved(cls, path: str | Path) -> "TrainConfig":
        """The config a run or a comparison wrote (``config.yaml``): every field is in it;
        a field added since it was written takes the paper's value, which is what the run
        used (every option was added off), so runs made before the recipe became the
        default resume as they began."""
        path = Path(path)
        d = read_yaml(path, "training config")
        if isinstance(d, dict):
            d = _resolve_paths(d, path)
        return cls.from_dict(d, where=str(path), base=cls.paper())


#: The named presets, for ``--config NAME`` and ``extends: NAME``.
PRESETS = ("recipe", "paper")

#: Fields whose mappings a file merges key by key into its base's (the rest it replaces).
MERGED_FIELDS = ("algo", "task")

#: The most files a chain of ``extends`` may hold below the file given.
MAX_EXTENDS_DEPTH = 32


def read_config_layers(path: Path, seen: tuple[Path, ...] = ()) -> tuple[dict, str]:
    """The fields of the training-config file ``path``, on top of those of the file its
    ``extends`` names (a path relative to ``path``'s folder), and so on down, and the preset
    at the bottom (``recipe`` unless the last ``extends`` names ``paper``): a variant file says
    only what it changes. ``algo`` and ``task`` are merged key by key; any other field
    replaces the base's. A relative ``constraints`` path is resolved against the folder of
    the file that gives it, so a run directory's copy and a base in another folder both keep
    pointing at the same file.

    Returns:
        (the merged fields, the name of the preset they lie on).

    Raises:
        InputError: naming the file: unreadable or not a mapping, an unknown field (named by
            the file that holds it, base or variant), ``extends`` not a string, a base that
            cannot be read, or a chain of bases that loops back.
    """
    where = str(path)
    d = read_yaml(path, "training config")
    if not isinstance(d, dict):
        raise InputError(f"{where}: expected a mapping of training settings")
    _check_layer_fields(d, where)
    d = dict(d)
    d = _resolve_paths(d, path)
    if "extends" not in d:
        return d, "recipe"
    name = d.pop("extends")
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"{where}: field 'extends' must name a config file (a path relative "
                         f"to this file's folder) or a preset {PRESETS}; got {name!r}")
    if name in PRESETS:
        return d, name
    if "\0" in name:
        raise InputError(f"{where}: field 'extends': a path cannot hold a NUL character; got {name!r}")
    if len(seen) >= MAX_EXTENDS_DEPTH:
        raise InputError(f"{where}: field 'extends': more than {MAX_EXTENDS_DEPTH} files in the "
                         "chain of bases")
    base_path = path.parent / name
    try:
        chain = (*seen, path.resolve())          # this file and the ones that extend it
        resolved = base_path.resolve()
    except (OSError, RuntimeError) as exc:       # a symlink loop
        raise InputError(f"{where}: field 'extends': cannot resolve {str(base_path)!r}: {exc}") from None
    if resolved in chain:
        looped = " -> ".join(str(p) for p in (*chain, resolved))
        raise InputError(f"{where}: field 'extends' loops back: {looped}")
    if not base_path.is_file():
        raise InputError(f"{where}: field 'extends': no config file {str(base_path)!r}")
    base, preset = read_config_layers(base_path, chain)
    for name_ in MERGED_FIELDS:
        if isinstance(base.get(name_), dict) and isinstance(d.get(name_), dict):
            d[name_] = {**base[name_], **d[name_]}
    return {**base, **d}, preset


#: Fields that name files or folders: a relative one is relative to the config file that gives it.
PATH_FIELDS = ("constraints", "demos")


def _resolve_paths(d: dict, path: Path) -> dict:
    """``d`` with its relative ``PATH_FIELDS`` made relative to ``path``'s folder."""
    d = dict(d)
    for name in PATH_FIELDS:
        if d.get(name) and isinstance(d[name], str) and not Path(d[name]).is_absolute():
            d[name] = str(path.parent / d[name])
    return d


def _check_layer_fields(d: dict, where: str) -> None:
    """Refuse unknown top-level and ``algo`` field names in one layer of a config file, so
    that a misspelt field in a base is reported under the base's name, not the variant's."""
    known = {f.name for f in fields(TrainConfig)} | {"extends"}
    unknown = sorted(set(d) - known - set(REMOVED_FIELDS), key=str)
    if unknown:
        raise InputError(f"{where}: unknown field(s) {unknown}; known: {sorted(known)}")
    if isinstance(d.get("algo"), dict):
        known_algo = {f.name for f in fields(DADDPGConfig)}
        unknown = sorted(set(d["algo"]) - known_algo - set(ALGO_REMOVED_FIELDS) - {"polyak"}, key=str)
        if unknown:
            raise InputError(f"{where}: algo: unknown DADDPG field(s) {unknown}; "
                             f"known: {sorted(known_algo)}")
