"""A trained policy from a run directory, for evaluation, videos and trajectory export."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dualarm.errors import InputError
from dualarm.rl.config import EVAL_ACTORS
from dualarm.rl.daddpg import DADDPG
from dualarm.training.config import TrainConfig
from dualarm.training.run_dir import CheckpointError, RunPaths, load_checkpoint

CHECKPOINTS = ("latest", "best")


def load_policy(run_dir: str | Path, which: str = "best") -> tuple[TrainConfig, DADDPG, dict]:
    """The run's config and a learner holding its actors and normaliser.

    Args:
        run_dir: a run directory of ``dualarm train``.
        which: "best" (the best evaluation; falls back to "latest" if the run has not been
            evaluated) or "latest" (the last checkpoint).

    Returns:
        (config, learner, info) with info {"checkpoint": path, "episodes": int or None,
        "eval": the best evaluation or None}.
    """
    return _load(run_dir, which, whole=False)


def load_learner(run_dir: str | Path) -> tuple[TrainConfig, DADDPG, dict]:
    """The run's config and its whole learner at the latest checkpoint: actors, critics,
    targets and normaliser (``load_policy`` restores the actors alone, which is all acting
    needs; a critic read from it would be its untrained initial weights).

    Returns:
        (config, learner, info) as ``load_policy``'s.
    """
    return _load(run_dir, "latest", whole=True)


def load_target_policy(run_dir: str | Path) -> tuple[TrainConfig, DADDPG, dict]:
    """The run's latest checkpoint with its target actors acting: the Polyak averages of the
    actors (Eq. 15, ``tau`` per update), an exponential moving average of the policy over
    about 1 / tau updates, which a run's last updates move less than the actors themselves.
    Only the latest checkpoint holds them (a best-policy file keeps the actors alone).

    Returns:
        (config, learner, info) as ``load_policy``'s; the learner's actors are its target
        actors (for acting and evaluating only: it is not a learner to continue training).
    """
    config, agent, info = load_learner(run_dir)
    agent.actor.load_state_dict(agent.actor_target.state_dict())
    return config, agent, info


def load_actors(run_dir: str | Path, which: str = "best",
                actors: str | None = None) -> tuple[TrainConfig, DADDPG, dict]:
    """The run's deterministic policy with the actors asked for.

    Args:
        run_dir: a run directory of ``dualarm train``.
        which: "best" or "latest", as ``load_policy``'s.
        actors: None for the run's own (``algo.eval_actor``, from ``which``); "online",
            "target" or "average" (``algo.policy_average``'s) for those actors: where they
            are not the run's own, from the latest checkpoint (a best-policy file holds the
            run's own actors alone).

    Returns:
        (config, learner, info) as ``load_policy``'s, plus info["actors"]: the actors acting.
    """
    if actors is not None and actors not in EVAL_ACTORS:
        raise InputError(f"actors must be one of {', '.join(EVAL_ACTORS)}, got {actors!r}")
    if actors is not None:
        paths = RunPaths(run_dir)
        own = TrainConfig.load_saved(paths.config).algo.eval_actor if paths.config.exists() else None
        if actors != own:
            config, agent, info = load_learner(run_dir)
            if actors == "average" and agent.actor_average is None:
                raise InputError(f"{run_dir}: has no averaged actors (its algo.policy_average is 0)")
            agent.actor.load_state_dict(agent.actors(actors).state_dict())
            agent.use_actors_everywhere()                      # act() may read any
            return config, agent, {**info, "actors": actors}
    config, agent, info = load_policy(run_dir, which)
    return config, agent, {**info, "actors": config.algo.eval_actor}


def policy_heading(info: dict) -> str:
    """"CHECKPOINT (after N training episodes[, target actors | , averaged actors])" for the
    ``info`` of ``load_actors``: the first words of what eval and diagnose print."""
    actors = {"target": ", target actors", "average": ", averaged actors"}.get(info.get("actors"), "")
    return f"{info['checkpoint']} (after {info['episodes']} training episodes{actors})"


def _load(run_dir: str | Path, which: str, whole: bool) -> tuple[TrainConfig, DADDPG, dict]:
    """Read the run's config and one checkpoint (once: a latest checkpoint holds the replay
    buffer too); restore the policy's parts, or with ``whole`` the whole learner."""
    if which not in CHECKPOINTS:
        raise InputError(f"checkpoint must be one of {CHECKPOINTS}, got {which!r}")
    paths = RunPaths(run_dir)
    if not paths.config.exists():
        raise InputError(f"{paths.root}: not a run directory (no config.yaml)")
    config = TrainConfig.load_saved(paths.config)
    path = paths.best if which == "best" and paths.best.exists() else paths.latest
    payload = load_checkpoint(path)
    if whole and "learner" not in payload:
        raise CheckpointError(f"{path}: holds no learner state (critics)")
    try:
        # a learner state holds the policy's parts (actor, normaliser, sizes) too
        state = payload["policy"] if "policy" in payload else payload["learner"]
        agent = DADDPG(config.algo, state["obs_sizes"], state["act_sizes"], seed=config.seed)
        if whole:
            agent.load_state_dict(state)
        else:
            agent.load_policy_state_dict(state)
        episodes = payload["eval"]["episode"] if "policy" in payload else payload["counters"]["episodes"]
    except (KeyError, ValueError, RuntimeError) as exc:
        raise CheckpointError(f"{path}: does not fit this run's networks ({exc})") from None
    info = {"checkpoint": path, "episodes": episodes, "eval": payload.get("eval")}
    return config, agent, info


def single_env_policy(agent: DADDPG):
    """The deterministic policy as a callable obs (2, O) -> actions (2, U) for one env."""
    return lambda obs: agent.act(np.asarray(obs)[None])[0]


def policy_env(run: Path, checkpoint: str = "best"):
    """A run's policy in a fresh copy of its task: (config, env, policy obs (2, O) -> actions
    (2, U), checkpoint info); the env has the run's constraints (close it when done)."""
    from dualarm.envs.baxter import BaxterReachGraspAlign

    config, agent, info = load_policy(run, checkpoint)
    env = BaxterReachGraspAlign(config.task_config(), config.load_constraints())
    return config, env, single_env_policy(agent), info


def policy_episode(run: Path, checkpoint: str, seed: int, camera: str | None = None,
                   size: tuple[int, int] | None = None, progress: bool = False):
    """One episode of a run's deterministic policy from ``reset(seed)`` (``progress``: a bar
    of its steps on stderr, for the seconds rendering takes). Returns (env, episode,
    checkpoint info)."""
    from dualarm.envs.rollout import run_episode

    config, env, policy, info = policy_env(run, checkpoint)
    if size:
        env.render_size = size
    bar = None
    if progress:
        import sys

        from tqdm import tqdm
        bar = tqdm(total=config.task_config().max_episode_steps, unit="step", desc="render",
                   file=sys.stderr)
    try:
        episode = run_episode(env, policy, seed, camera=camera,
                              on_step=bar.update if bar is not None else None)
    finally:
        if bar is not None:
            bar.close()
    env.close()
    return env, episode, info
