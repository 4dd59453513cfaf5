"""The hyper-parameters of DADDPG, each with what it does and why it has its value."""

from __future__ import annotations

from dataclasses import dataclass

from dualarm.errors import InputError
from dualarm.typed_fields import ANY, Settings, check_field_types


#: The actors a deterministic policy can act with (``DADDPGConfig.eval_actor``).
EVAL_ACTORS = ("online", "target", "average")

#: Options removed from DADDPGConfig, with the one value a file may still give (old run
#: directories keep loading); docs/learning-runs.md and docs/training.md name the commit that
#: had each and what it measured.
REMOVED_FIELDS = {"noise": "gaussian", "value_rescale": False, "advantage_learning": 0.0,
                  "ou_theta": ANY, "grip_hold_eps": 0.0, "grip_hold_steps": ANY,
                  "free_grip": False, "critic_layer_norm": False, "random_grip": True,
                  "policy_delay": 1, "pretrain_updates": 0, "n_step": 1,
                  "clone_updates": 0, "critic_warmup": 0, "demo_return_floor": False}


#: Size bounds: these fields decide memory before the first step (a network of width 10**12
#: asks for petabytes), so they are bounded where the config is read.
MAX_LAYERS, MAX_WIDTH = 8, 4096
MAX_BATCH, MAX_BUFFER = 65_536, 10_000_000
SIZE_BOUNDS = {"hidden": f" (1 to {MAX_LAYERS} layers of 1 to {MAX_WIDTH} units)",
               "batch_size": f" (1 to {MAX_BATCH})",
               "buffer_size": f" (batch_size to {MAX_BUFFER:,} transitions)"}


@dataclass(frozen=True)
class DADDPGConfig(Settings):
    """Dual-agent DDPG settings. Defaults start from Plappert et al. 2018 (DDPG+HER on Fetch)
    and were tuned on the Baxter task with ``benchmarks/update_speed.py`` and short runs;
    docs/training.md records the measurements behind each change.
    """

    LABEL = "DADDPG"
    REMOVED = REMOVED_FIELDS
    OLD_NAMES = ("polyak",)

    @classmethod
    def upgrade(cls, d: dict, where: str) -> dict:
        """A settings dict of an older layout in today's: ``polyak`` -> ``tau``, removed options
        dropped where they have the value that is today's behaviour."""
        if "polyak" in d:
            if "tau" in d:
                raise InputError(f"{where}: give tau or polyak (tau = 1 - polyak), not both")
            d = dict(d)
            polyak = d.pop("polyak")
            d["tau"] = 1.0 - polyak if isinstance(polyak, (int, float)) and not isinstance(polyak, bool) else polyak
        return super().upgrade(d, where)

    hidden: tuple[int, ...] = (256, 256)
    """Hidden layer widths of every actor and critic (Plappert: 3 x 256; 2 x 256 halves the
    update time, benchmarks/update_speed.py)."""
    actor_lr: float = 3e-4
    """Adam learning rate of the actors (Plappert: 1e-3; 3e-4 kept the arms from pushing the
    boxes away as often on the reach sub-task, docs/training.md)."""
    critic_lr: float = 1e-3
    """Adam learning rate of the critics (Plappert: 1e-3)."""
    batch_size: int = 256
    """Transitions per update (Plappert: 256)."""
    gamma: float = 0.98
    """Discount factor of Eq. 13 (Plappert: 0.98; 50-step episodes)."""
    tau: float = 0.005
    """Eq. 15's tau: target networks move this fraction of the way per update. Plappert's
    polyak 0.95 is per cycle of 40 updates (tau ~0.0013 per update); 0.05 per update made Q
    diverge here. (Files that say ``polyak: P`` are read as tau = 1 - P.)"""
    buffer_size: int = 1_000_000
    """Replay capacity in joint transitions (Plappert: 1e6)."""
    noise_std: float = 0.1
    """Standard deviation of the noise in action units, actions span [-1, 1] (Plappert: 0.2;
    0.1 is 5 mm per step here, enough next to a 2 cm reach tolerance)."""
    random_eps: float = 0.0
    """Probability of a uniformly random action per step and agent (Plappert: 0.3; random
    jumps of up to 5 cm knock the boxes over: 0 reached the boxes ~2x as often)."""
    action_l2: float = 0.1
    """Weight of the mean squared action in the actor loss (Plappert: 1.0, made for returns of
    -50..0; with this task's distance rewards 1.0 kept the arms nearly still)."""
    obs_clip: float = 5.0
    """Normalised observations are clipped to +-obs_clip (Plappert: 5)."""
    grad_clip: float = 10.0
    """Max global gradient norm per agent and network (0 turns clipping off)."""
    reward_scale: float = 1.0
    """Rewards are multiplied by this before the critic sees them (curves log raw rewards)."""
    q_clip: float = 0.0
    """If > 0, critic targets are clipped to +-q_clip (in scaled reward units)."""
    twin_critics: bool = False
    """Two critics per agent, targets from their minimum (TD3's fix of over-estimation)."""
    target_noise: float = 0.0
    """Std of clipped noise on the target actions of Eq. 13 (TD3's smoothing; 0 = off)."""
    twin_min_weight: float = 1.0
    """beta in [0, 1]: with twin critics the target is beta min(Q'1, Q'2) + (1 - beta) of their
    mean (WD3, He and Hou 2020): less of the minimum's under-estimation, which compounds
    over the steps between a success and the reset (docs/learning-runs.md).
    1 = TD3's minimum."""
    demo_batch_size: int = 0
    """Transitions drawn from the demonstration buffer into every update, next to
    ``batch_size`` from replay (Nair et al. 2018; needs demonstrations, e.g. TrainConfig's
    ``demos.episodes``). 0: demonstrations are not used, as in the paper."""
    bc_weight: float = 0.0
    """Weight of the behaviour-cloning term on the demonstration rows of a batch, Q-filtered:
    only where the critic rates the demonstrated action above the actor's (Nair et al. 2018)."""
    updates_per_step: float = 0.5
    """Gradient updates per joint environment step (the update-to-data ratio)."""
    eval_actor: str = "online"
    """The actors the deterministic policy acts with (evaluations, the best policy file,
    ``dualarm eval/play/export``; the curriculum's probes always act with the online actors,
    so this choice does not change training): "online", the actors the gradient trains, or
    "target", their Polyak averages (Eq. 15), which a run's last updates move less
    (docs/learning-runs.md), or "average", the slower averages of
    ``policy_average``. Exploring actions always come from the online actors."""
    policy_average: float = 0.0
    """Rate per update of a second, slower exponential average of the online actors, kept for
    acting alone (Polyak-Ruppert averaging of the policy; Nikishin et al. 2018 average an
    RL policy's weights for stability): 0.001 averages over about 1,000 updates, where the
    target actors' ``tau`` 0.005 averages over 200. Each evaluation also evaluates these
    actors (eval.csv's ``average_success_rate`` and ``average_return_mean``) without
    changing training; ``eval_actor: average`` makes them the run's policy. 0: none."""
    warmup_steps: int = 1000
    """Joint environment steps of uniformly random actions before learning starts."""
    bf16_matmuls: bool = False
    """Mixed precision: the hidden layers' matrix products in bfloat16, everything else
    (weights, Adam, output layers, losses) in float32. About 1.5 times faster updates on a CPU
    with native bfloat16 (AVX512-BF16 or AMX); slower elsewhere (a warning says so). Learning
    measured the same within the seeds' spread (docs/benchmarks.md)."""

    def __post_init__(self):
        check_field_types(self)
        checks = {
            "hidden": 1 <= len(self.hidden) <= MAX_LAYERS
                      and all(1 <= h <= MAX_WIDTH for h in self.hidden),
            "actor_lr": self.actor_lr > 0, "critic_lr": self.critic_lr > 0,
            "batch_size": 1 <= self.batch_size <= MAX_BATCH, "gamma": 0 <= self.gamma < 1,
            "tau": 0 < self.tau <= 1, "buffer_size": self.batch_size <= self.buffer_size <= MAX_BUFFER,
            "noise_std": self.noise_std >= 0, "random_eps": 0 <= self.random_eps <= 1,
            "action_l2": self.action_l2 >= 0, "obs_clip": self.obs_clip > 0,
            "grad_clip": self.grad_clip >= 0, "reward_scale": self.reward_scale > 0,
            "q_clip": self.q_clip >= 0, "target_noise": self.target_noise >= 0,
            "twin_min_weight": 0 <= self.twin_min_weight <= 1 and (self.twin_critics or self.twin_min_weight == 1),
            "updates_per_step": self.updates_per_step >= 0,
            "demo_batch_size": self.demo_batch_size >= 0, "bc_weight": self.bc_weight >= 0,
            "warmup_steps": self.warmup_steps >= 0, "eval_actor": self.eval_actor in EVAL_ACTORS,
            "policy_average": 0 <= self.policy_average <= 1,
        }
        bad = [name for name, ok in checks.items() if not ok]
        if bad:
            name = bad[0]
            raise InputError(f"{name}: invalid value {getattr(self, name)!r}"
                             + SIZE_BOUNDS.get(name, ""))
        if self.eval_actor == "average" and self.policy_average == 0:
            raise InputError("eval_actor: 'average' needs averaged actors (policy_average > 0)")

