"""Demonstration transitions for the replay: episodes of the scripted expert, recorded with
the same environment, rewards and round runner as training (Nair et al. 2018's
demonstration buffer). An option beyond the paper: its three conditions use none."""

from __future__ import annotations

import sys

import numpy as np

from dualarm.envs.starts import RecordedStates
from dualarm.rl.replay import ReplayBuffer
from dualarm.training.config import TrainConfig
from dualarm.training.evaluation import evaluate
from dualarm.training.vector import VectorEnv

#: Demonstration episode j is reset with ``seeds_for(DEMO_SEED_BASE + run seed, 0, N)[j]``:
#: placements other than those of the run's training episodes.
DEMO_SEED_BASE = 1_000_003


def demonstrations(config: TrainConfig, vec: VectorEnv, constraints
                   ) -> tuple[ReplayBuffer | None, RecordedStates | None]:
    """The run's demonstration buffer: the recordings of ``config.demos.folder``
    (``record_recording_replays``), else ``config.demos.episodes`` of the scripted expert in
    ``vec`` (``record_expert_demonstrations``), else None (also with ``demos.buffer`` false);
    and with ``config.demos.starts`` the successful replays' states to start training
    episodes from, else None."""
    if config.demos.recordings:
        replays = successful_replays(config, constraints,
                                     log=lambda line: print(line, file=sys.stderr))
        states = recorded_states(replays) if config.demos.starts else None
        if not config.demos.buffer:
            return None, states
        return record_recording_replays(config, constraints, replays=replays), states
    if config.demos.episodes:
        return record_expert_demonstrations(config, vec), None
    return None, None


def recorded_states(replays) -> RecordedStates:
    """The scenes and step-by-step states of successful ``replays`` (``Replay``), to start
    training episodes from (``StartDistribution.states``): each but its last state, where the
    episode had already succeeded."""
    return RecordedStates.from_episodes(
        [{k: v[:-1] if k in ("qpos", "fingers", "subtask") else v for k, v in r.states.items()}
         for r in replays])


def record_expert_demonstrations(config: TrainConfig, vec: VectorEnv) -> ReplayBuffer:
    """Run ``config.demos.episodes`` episodes of ``ScriptedExpert`` in ``vec`` (the run's
    Baxter task, cartesian control: ``TrainConfig`` checks it) and return their transitions
    (obs and next_obs (N, 2, O), act (N, 2, U), rew (N, 2), done (N,))."""
    from dualarm.envs.expert import ScriptedExpert

    task = config.task_config()
    expert = ScriptedExpert(task)
    buffer = ReplayBuffer(max(1, config.demos.episodes * task.max_episode_steps), 2,
                          vec.obs_size, vec.act_size)

    def act(obs: np.ndarray) -> np.ndarray:
        return np.stack([expert(o) for o in obs])

    def store(obs, actions, step, live):
        buffer.add(obs[live], actions[live], step.reward[live], step.obs[live],
                   step.terminated[live])

    evaluate(act, vec, config.demos.episodes, DEMO_SEED_BASE + config.seed, on_step=store)
    return buffer


def record_recording_replays(config: TrainConfig, constraints, log=None,
                             replays=None) -> ReplayBuffer:
    """The transitions of ``successful_replays`` (or of ``replays``, those already made), their
    actions permuted within each episode with ``config.demos.shuffle`` (the control): obs and
    next_obs (N, 2, O), act (N, 2, U), rew (N, 2), done (N,)."""
    if replays is None:
        replays = successful_replays(config, constraints, log)
    rng = np.random.default_rng([config.seed, 3])
    kept = [{"obs": r.obs, "act": r.act[rng.permutation(len(r.act))] if config.demos.shuffle else r.act,
             "rew": r.rew,
             "next_obs": r.next_obs, "done": r.done} for r in replays]
    rows = sum(len(e["done"]) for e in kept)
    buffer = ReplayBuffer(rows, 2, kept[0]["obs"].shape[-1], kept[0]["act"].shape[-1])
    for e in kept:
        buffer.add(e["obs"], e["act"], e["rew"], e["next_obs"], e["done"])
    return buffer


def successful_replays(config: TrainConfig, constraints, log=None) -> list:
    """Replay the recordings of ``config.demos.folder`` at their own scenes in the run's task
    (condition, constraints and observation as training's; ``dualarm.sim_demos.replay``; in a
    joint-control task each cartesian replay is done again in joint space, ``in_joint_control``), and
    with ``config.demos.episodes`` moved to that many of the task's random placements
    (``dualarm.sim_demos.augment``, placements seeded from ``DEMO_SEED_BASE`` + the run's
    seed), and return those that succeed (``Replay``, the recordings' own first).

    Args:
        log: called with one line per recording left out (its replay did not succeed).

    Raises:
        InputError: the folder, its labels or its scene are missing or bad, or no recording
            replays to success.
    """
    from dualarm.envs.baxter import BaxterReachGraspAlign
    from dualarm.errors import InputError
    from dualarm.sim_demos.augment import augment
    from dualarm.sim_demos.replay import in_joint_control, load_replay_folder, replay_demonstration

    task = config.task_config()
    demos, labels, scenes = load_replay_folder(config.demos.folder, task.workspace())
    env = BaxterReachGraspAlign(task.with_(control="cartesian"), constraints)   # follows hand paths
    # The learner's task; in joint control each cartesian replay is done again there.
    learner = env if task.control == "cartesian" else BaxterReachGraspAlign(task, constraints)

    def in_task(r, scene):
        return r if learner is env else in_joint_control(learner, r, scene)

    try:
        replays, usable, left_out = [], [], []
        for d in demos:
            if d.grip is None:
                left_out.append(f"{d.source}: no gripper events (left_grip, right_grip columns)")
                continue
            r = replay_demonstration(env, d, labels[d.name], scenes[d.name])
            if r.success:
                usable.append(d)
                r = in_task(r, scenes[d.name])
            if not r.success:
                left_out.append(f"{d.source}: its replay at its scene does not succeed in "
                                f"{task.control} control ({r.why})")
                continue
            replays.append(r)
        if usable and config.demos.episodes:
            moved = augment(env, usable, labels, scenes, config.demos.episodes,
                            DEMO_SEED_BASE + config.seed)
            moved_ok = [m for m in (in_task(r, p) for r, p in zip(moved.replays, moved.placements))
                        if m.success]
            replays += moved_ok
            if log is not None:
                log(f"demos: {len(moved_ok)} of {moved.attempts} recordings moved to new placements "
                    f"succeed" + ("" if learner is env else " (in cartesian control, then in joint control)"))
    finally:
        env.close()
        if learner is not env:
            learner.close()
    for line in left_out:
        if log is not None:
            log(f"demos: left out {line}")
    if not replays:
        raise InputError(f"none of the {len(demos)} recordings replays to success at its scene "
                         "(`dualarm demos replay` shows where each stops)", source=str(config.demos.folder))
    return replays
