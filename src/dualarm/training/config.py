"""Everything a training run is made of, in one typed value saved as ``config.yaml``.

``TrainConfig()`` is **the recipe**: the settings under which DADDPG learns the whole task
without demonstrations, in every condition (how each was found and what it measured:
docs/learning-runs.md). ``TrainConfig.paper()`` is the paper's plain DDPG, the reproduction's
baseline (``--config paper``), which does not learn the full task.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import yaml

from dualarm.errors import InputError
from dualarm.rl.config import DADDPGConfig
from dualarm.task import MAX_SEED
from dualarm.training.config_groups import (FLAT_FIELDS, GROUPS, OFF, Demos, NearBox, Replay,
                                            Shaping, Starts, nest_flat_fields)
from dualarm.typed_fields import check_field_types, drop_removed_fields, plain
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
    updates_per_step=1.0,      # 0.85 about 3x sooner than 0.25, once replay mirrored and recombined
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
#: rows per update from the demonstration buffer and the weight of Q-filtered behaviour cloning
#: (Nair et al. 2018) in the actor's loss on the recipe's value scale (rc = 1). The updates per
#: step are the recipe's, so that the demos condition differs from multi in the demonstrations
#: alone (from 2026-12-06 to the recipe's change to 1.0 they were raised here, a confound;
#: docs/human-demos, section 7). ``with_demos_algo`` keeps the values a config chose.
DEMOS_ALGO = {"demo_batch_size": 64, "bc_weight": 1.0}


def with_demos_algo(algo: DADDPGConfig) -> DADDPGConfig:
    """``algo`` with ``DEMOS_ALGO``'s values in the fields that hold a preset's value (the
    recipe's or the paper's): a value a config chose (``bc_weight: 3``, say) is
    kept, where it was once silently replaced. To keep a preset's own value beside the
    recordings, set ``demo_batch_size`` too: a config that draws demonstration rows gets no
    DEMOS_ALGO at all."""
    presets = (RECIPE_ALGO, DADDPGConfig())
    return algo.with_(**{name: value for name, value in DEMOS_ALGO.items()
                         if any(getattr(algo, name) == getattr(p, name) for p in presets)})


#: ... and the demonstration episodes made from the recordings by moving them to new
#: placements (``demos.episodes``): 64 scripted-expert episodes were too few, 256 enough.
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
    """A training run of DADDPG on the Baxter task. The defaults are the recipe (the learner's
    in ``RECIPE_ALGO``); ``TrainConfig.paper()`` turns every option beyond the paper off.
    Options that the recipe leaves off were measured and not adopted (docs/learning-runs.md,
    "Tried and not adopted").

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
        stop_at: end the run after the first evaluation whose success rate reaches this
            (for example 0.85, the report's target): the run is then done, and a resume or a
            larger ``episodes`` trains no further. None: train all ``episodes``.
        checkpoint_every: training episodes between checkpoints (0: only by time and at the end).
        checkpoint_minutes: wall-clock minutes between checkpoints.
        torch_threads: PyTorch intra-op threads (1 gives bit-reproducible runs).
        starts: where training episodes begin (``Starts``: probabilities, reverse curriculum,
            its probe, approach starts).
        replay: what the replay makes of the stored steps (``Replay``: hindsight targets,
            recombined arms, mirrored episodes).
        shaping: potential-based shaping towards the box and the target (``Shaping``).
        near_box: the action penalty and random actions within and beyond a radius of the box
            (``NearBox``).
        demos: the demonstration buffer (``Demos``: people's recordings or the scripted
            expert, how many moved episodes, the shuffled control).
        algo: the DADDPG hyper-parameters.

    A group given as a mapping (``TrainConfig(replay={"her_share": 0})``) takes the recipe's
    values for the fields it leaves out; ``with_`` merges it into the config's own.
    """

    condition: str = "multi"
    constraints: str | None = None
    task: dict = field(default_factory=_recipe_task)
    episodes: int = 10000
    seed: int = 0
    num_envs: int = 16
    eval_every: int = 160
    eval_episodes: int = 50
    stop_at: float | None = None
    checkpoint_every: int = 0
    checkpoint_minutes: float = 2.0
    torch_threads: int = 1
    starts: Starts = Starts()
    replay: Replay = Replay()
    shaping: Shaping = Shaping()
    near_box: NearBox = NearBox()
    demos: Demos = Demos()
    algo: DADDPGConfig = RECIPE_ALGO

    def __post_init__(self):
        for name, kind in GROUPS.items():
            value = getattr(self, name)
            if not isinstance(value, kind):
                object.__setattr__(self, name, kind.from_dict(value, where=name))
        check_field_types(self)
        from dualarm.task import CONDITIONS
        if self.condition not in CONDITIONS:
            raise InputError(f"condition must be one of {CONDITIONS}, got {self.condition!r}")
        unknown = sorted(set(self.task) - set(TASK_OVERRIDES), key=str)
        if unknown:
            raise InputError(f"task overrides {unknown} are not supported; allowed: {TASK_OVERRIDES}")
        if self.demos.recordings:
            if self.algo.demo_batch_size == 0 and self.demos.buffer:   # drawn as DEMOS_ALGO says
                object.__setattr__(self, "algo", with_demos_algo(self.algo))
            if self.demos.episodes == 0:                # whatever the algo says: they are moved
                object.__setattr__(self, "demos", self.demos.with_(episodes=DEMOS_EPISODES))
        # an override that gives the task's own default is no override: one config, one value
        object.__setattr__(self, "task", {k: v for k, v in self.task.items()
                                          if not _is_task_default(k, v)})
        for name in ("episodes", "num_envs", "torch_threads"):
            if getattr(self, name) < 1:
                raise InputError(f"{name} must be at least 1, got {getattr(self, name)}")
        if not 0 <= self.seed <= MAX_SEED:
            raise InputError(f"seed must be in 0..{MAX_SEED}, got {self.seed}")
        for name in ("eval_every", "eval_episodes", "checkpoint_every"):
            if getattr(self, name) < 0:
                raise InputError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.stop_at is not None and not (0 < self.stop_at <= 1 and self.eval_every
                                             and self.eval_episodes):
            raise InputError(f"stop_at must be in (0, 1] and needs evaluations (eval_every and "
                             f"eval_episodes > 0), got {self.stop_at}")
        if self.checkpoint_minutes <= 0:
            raise InputError(f"checkpoint_minutes must be > 0, got {self.checkpoint_minutes}")
        self._check_across_groups()

    def _check_across_groups(self) -> None:
        """The checks that join a group to the task, the evaluations or the learner (each
        group checks its own values)."""
        try:
            task = self.task_config()
        except InputError as exc:
            raise InputError(f"task: {exc}") from None
        if self.algo.demo_batch_size > 0 and self.demos.episodes == 0:
            raise InputError("algo.demo_batch_size > 0 draws from demonstrations: set demos.folder "
                             "(a demonstration folder) or demos.episodes")
        if self.demos.recordings:
            from dualarm.sim_demos.replay import DEFAULT_STEPS
            if task.max_episode_steps < DEFAULT_STEPS:
                raise InputError(f"demos: a recording is retimed to {DEFAULT_STEPS} steps, longer "
                                 f"than task.max_episode_steps {task.max_episode_steps}")
        elif self.demos.episodes and task.control != "cartesian":
            raise InputError("demos.episodes: the scripted expert demonstrates cartesian control "
                             "only, not task.control 'joint'")
        if self.algo.demo_batch_size > 0 and self.demos.recordings and not self.demos.buffer:
            raise InputError("algo.demo_batch_size > 0 draws from the demonstration buffer, "
                             "which demos.buffer: false leaves empty")
        if self.demos.starts and not self.starts.later:
            raise InputError("demos.starts takes the later starts from the recordings: give "
                             "starts.probs other than (1, 0, 0), for example [0.2, 0.2, 0.6]")
        if self.starts.probe and not self.eval_every:
            raise InputError("starts.probe measures the curriculum at every evaluation: give "
                             "eval_every too")
        if self.replay.recombine_share > 0 and task.success_at == "reach":
            raise InputError(f"replay.recombine_share works on the full task, got "
                             f"{self.replay.recombine_share} with task.success_at 'reach'")
        if self.replay.mirror and self.condition != "none" and not task.observes_joint_angles:
            raise InputError("replay.mirror in a guided condition needs the joint angles in the "
                             "observation (task: {joint_angles_in_obs: true}): the mirrored guide "
                             "term is computed from them")

    def baxter_only_options(self) -> list[str]:
        """The options set in this config that exist for the Baxter task only (a custom
        PettingZoo environment has no scripted expert, start states, targets or reward terms)."""
        off = self.paper()
        return [name for name in ("starts", "replay", "shaping", "near_box", "demos")
                if getattr(self, name) != getattr(off, name)]

    @property
    def compared_condition(self) -> str:
        """The run's condition in a comparison: ``DEMOS_CONDITION`` with recordings as
        demonstrations, else ``condition``."""
        from dualarm.task import DEMOS_CONDITION

        return DEMOS_CONDITION if self.demos.recordings else self.condition

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
        """A copy with some fields changed (checked as a new config is); a group given as a
        mapping (or ``demos`` as a folder) changes only the fields it names."""
        for name, kind in SECTIONS.items():
            if name in changes and not isinstance(changes[name], kind):
                changes[name] = kind.from_dict(changes[name], where=name, base=getattr(self, name))
        return replace(self, **changes)

    def stored_in(self, root: str | Path) -> "TrainConfig":
        """The config as the run directory ``root`` keeps it, so that it reads the same from any
        working directory: each of ``PATH_FIELDS`` made absolute, except a path inside ``root``
        (the run's own constraints copy), named relative to it (``load_saved`` resolves a
        relative path against the directory)."""
        root = Path(os.path.abspath(root))
        config = self
        for group, name in PATH_FIELDS:
            section = config if group is None else getattr(config, group)
            value = getattr(section, name)
            if not value:
                continue
            full = Path(os.path.abspath(value))
            stored = str(full.relative_to(root)) if full.is_relative_to(root) else str(full)
            if stored != value:
                config = (config.with_(**{name: stored}) if group is None else
                          config.with_(**{group: section.with_(**{name: stored})}))
        return config

    def to_dict(self) -> dict:
        d = {f.name: plain(getattr(self, f.name)) for f in fields(self)}
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
        d = nest_flat_fields(drop_removed_fields(d, REMOVED_FIELDS, where), where)
        unknown = sorted(set(d) - known, key=str)
        if unknown:
            raise InputError(f"{where}: unknown field(s) {unknown}; known: {sorted(known)}")
        d = merge_layers(base.to_dict(), d)
        for name, kind in SECTIONS.items():
            d[name] = kind.from_dict(d[name] or {}, where=f"{where}: {name}")
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
        return cls(episodes=3000, eval_every=100, task={}, **OFF, algo=DADDPGConfig())

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
        changes = nest_flat_fields(changes, "the command line")
        return cls.from_dict(merge_layers(d, changes), where=str(path), base=cls.preset(base))

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

#: The config's settings objects by field name: the groups and the learner's.
SECTIONS = {**GROUPS, "algo": DADDPGConfig}

#: Fields whose mappings a file merges key by key into its base's (the rest it replaces).
MERGED_FIELDS = ("algo", "task", *GROUPS)


def merge_layers(base: dict, top: dict) -> dict:
    """Training settings ``top`` on top of ``base`` (both in the grouped layout): a group,
    ``algo`` and ``task`` merged key by key, any other field replaced."""
    merged = {**base, **top}
    for name in MERGED_FIELDS:
        if isinstance(base.get(name), dict) and isinstance(top.get(name), dict):
            merged[name] = {**base[name], **top[name]}
    return merged

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
    return merge_layers(base, d), preset


#: Fields that name files or folders, as (group or None, field): a relative one is relative to
#: the config file that gives it.
PATH_FIELDS = ((None, "constraints"), ("demos", "folder"))


def _resolve_paths(d: dict, path: Path) -> dict:
    """``d``, read from ``path``, in the grouped layout with its relative ``PATH_FIELDS`` made
    relative to ``path``'s folder."""
    d = nest_flat_fields(d, str(path))
    for group, name in PATH_FIELDS:
        section = d if group is None else d.get(group)
        if not isinstance(section, dict):
            continue
        value = section.get(name)
        if value and isinstance(value, str) and not Path(value).is_absolute():
            section = {**section, name: str(path.parent / value)}
            d = section if group is None else {**d, group: section}
    return d


def _check_layer_fields(d: dict, where: str) -> None:
    """Refuse unknown top-level and ``algo`` field names in one layer of a config file, so
    that a misspelt field in a base is reported under the base's name, not the variant's."""
    known = {f.name for f in fields(TrainConfig)} | {"extends"}
    unknown = sorted(set(d) - known - set(REMOVED_FIELDS) - set(FLAT_FIELDS), key=str)
    if unknown:
        raise InputError(f"{where}: unknown field(s) {unknown}; known: {sorted(known)}")
    for name, kind in SECTIONS.items():
        if isinstance(d.get(name), dict):
            kind.check_names(d[name], f"{where}: {name}")
