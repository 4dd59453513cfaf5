"""Run episodes of the dual-arm task with a policy: returns, success, frames."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from dualarm.envs.baxter import BaxterReachGraspAlign
from dualarm.envs.expert import ScriptedExpert

POLICIES = ("expert", "random")

#: A policy maps observations (2, obs_size) to actions (2, action_size) in [-1, 1].
Policy = Callable[[np.ndarray], np.ndarray]


def make_policy(name: str, env: BaxterReachGraspAlign, seed: int = 0) -> Policy:
    """A built-in policy by name: "expert" (scripted, cartesian only) or "random" (uniform)."""
    if name == "expert":
        return ScriptedExpert(env.config)
    if name == "random":
        rng = np.random.default_rng(seed)
        return lambda obs: rng.uniform(-1.0, 1.0, (2, env.action_size))
    raise ValueError(f"policy must be one of {POLICIES}, got {name!r}")


@dataclass
class Episode:
    """One episode's outcome.

    Attributes:
        seed: the reset seed.
        success: both boxes reached their targets.
        steps: environment steps taken.
        returns: (2,) summed rewards of the left and right arm.
        subtasks: (steps, 2) sub-task index of each arm after each step.
        joint_angles: (steps + 1, 14) Baxter joint angles (rad) from the reset on.
        actions: (steps, 2, action_size) the actions taken, clipped to [-1, 1] as the env
            applies them.
        frames: rendered RGB frames, if asked for.
    """

    seed: int
    success: bool
    steps: int
    returns: np.ndarray
    subtasks: np.ndarray
    joint_angles: np.ndarray
    actions: np.ndarray
    frames: list[np.ndarray] = field(default_factory=list)


def run_episode(env: BaxterReachGraspAlign, policy: Policy, seed: int,
                camera: str | None = None, on_step=None) -> Episode:
    """Run one episode from ``reset(seed)`` until it terminates or is truncated.

    Args:
        camera: render a frame after the reset and after every step from this camera.
        on_step: called with no arguments after every step (a progress bar's update).
    """
    obs, _ = env.reset(seed=seed)
    frames = [env.render(camera)] if camera else []
    returns = np.zeros(2)
    subtasks, joints, actions = [], [env.joint_angles()], []
    while True:
        action = np.clip(policy(obs), -1.0, 1.0)
        actions.append(action)
        result = env.step(action)
        obs = result.obs
        returns += result.reward
        subtasks.append(result.info["subtask"].copy())
        joints.append(env.joint_angles())
        if camera:
            frames.append(env.render(camera))
        if on_step is not None:
            on_step()
        if result.terminated or result.truncated:
            break
    return Episode(seed, bool(result.info["is_success"]), env.steps, returns,
                   np.array(subtasks), np.array(joints), np.array(actions), frames)


def expert_rollouts(episodes: int, seed: int = 1000, progress: bool = False
                    ) -> tuple[np.ndarray, np.ndarray, float]:
    """Joint angles and sub-tasks of the scripted expert over seeded episodes.

    Args:
        episodes: number of episodes (reset seeds ``seed .. seed + episodes - 1``).
    Returns:
        q (N, 14) rad, the joint angles after each step of every episode; subtasks (N, 2),
        each arm's sub-task after that step; the success rate.

    Raises:
        InputError: a seed of the range lies outside 0..``MAX_SEED``.
    """
    from dualarm.envs import make_core
    from dualarm.errors import InputError
    from dualarm.task import MAX_SEED

    if seed < 0 or seed + episodes - 1 > MAX_SEED:
        raise InputError(f"seeds {seed}..{seed + episodes - 1} ({episodes} episodes from seed {seed}) "
                         f"leave 0..{MAX_SEED}; choose a smaller --seed or fewer --episodes")

    env = make_core()
    policy = make_policy("expert", env)
    seeds = range(seed, seed + episodes)
    if progress:
        import sys

        from tqdm import tqdm
        seeds = tqdm(seeds, desc="expert", unit="ep", file=sys.stderr)
    qs, subs, wins = [], [], 0
    try:
        for s in seeds:
            ep = run_episode(env, policy, s)
            qs.append(ep.joint_angles[1:])
            subs.append(ep.subtasks)
            wins += ep.success
    finally:
        env.close()
    return np.concatenate(qs), np.concatenate(subs), wins / episodes
