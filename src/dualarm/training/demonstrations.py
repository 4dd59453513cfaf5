"""Demonstration transitions for the replay: episodes of the scripted expert, recorded with
the same environment, rewards and round runner as training (Nair et al. 2018's
demonstration buffer). An option beyond the paper: its three conditions use none."""

from __future__ import annotations

import numpy as np

from dualarm.rl.replay import ReplayBuffer
from dualarm.training.config import TrainConfig
from dualarm.training.rounds import run_round
from dualarm.training.vector import VectorEnv, seeds_for

#: Demonstration episodes are seeded ``seeds_for(DEMO_SEED_BASE + run seed, k, 1)``: placements
#: other than those of the run's training episodes.
DEMO_SEED_BASE = 1_000_003


def record_expert_demonstrations(config: TrainConfig, vec: VectorEnv) -> ReplayBuffer:
    """Run ``config.demo_episodes`` episodes of ``ScriptedExpert`` in ``vec`` (the run's task)
    and return their transitions (obs and next_obs (N, 2, O), act (N, 2, U), ...).

    Raises:
        ValueError: the task is not the Baxter task in cartesian control (the expert's).
    """
    from dualarm.envs.expert import ScriptedExpert

    task = config.task_config()
    if not getattr(vec, "has_subtasks", False) or task.control != "cartesian":
        raise ValueError("demo_episodes: the scripted expert demonstrates the Baxter task in "
                         "cartesian control only")
    expert = ScriptedExpert(task)
    buffer = ReplayBuffer(max(1, config.demo_episodes * task.max_episode_steps), 2,
                          vec.obs_size, vec.act_size)

    def act(obs: np.ndarray) -> np.ndarray:
        return np.stack([expert(o) for o in obs])

    def store(obs, actions, step, live):
        buffer.add(obs[live], actions[live], step.reward[live], step.obs[live],
                   step.terminated[live])

    done = 0
    while done < config.demo_episodes:
        n = min(vec.num_envs, config.demo_episodes - done)
        run_round(vec, seeds_for(DEMO_SEED_BASE + config.seed, done, n), act, store)
        done += n
    return buffer
