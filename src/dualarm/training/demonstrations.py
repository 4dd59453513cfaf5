"""Demonstration transitions for the replay: episodes of the scripted expert, recorded with
the same environment, rewards and round runner as training (Nair et al. 2018's
demonstration buffer). An option beyond the paper: its three conditions use none."""

from __future__ import annotations

import numpy as np

from dualarm.rl.replay import ReplayBuffer
from dualarm.training.config import TrainConfig
from dualarm.training.evaluation import evaluate
from dualarm.training.vector import VectorEnv

#: Demonstration episode j is reset with ``seeds_for(DEMO_SEED_BASE + run seed, 0, N)[j]``:
#: placements other than those of the run's training episodes.
DEMO_SEED_BASE = 1_000_003


def record_expert_demonstrations(config: TrainConfig, vec: VectorEnv, reward_of=None,
                                 reward_size: int = 1) -> ReplayBuffer:
    """Run ``config.demo_episodes`` episodes of ``ScriptedExpert`` in ``vec`` (the run's
    Baxter task, cartesian control: ``TrainConfig`` checks it) and return their transitions
    (obs and next_obs (N, 2, O), act (N, 2, U), ...). ``reward_of`` maps a step to the
    rewards stored ((n, 2) or (n, 2, reward_size); default: the step's reward)."""
    from dualarm.envs.expert import ScriptedExpert

    task = config.task_config()
    expert = ScriptedExpert(task)
    buffer = ReplayBuffer(max(1, config.demo_episodes * task.max_episode_steps), 2,
                          vec.obs_size, vec.act_size, reward_size)

    def act(obs: np.ndarray) -> np.ndarray:
        return np.stack([expert(o) for o in obs])

    def store(obs, actions, step, live):
        reward = step.reward if reward_of is None else reward_of(step)
        buffer.add(obs[live], actions[live], reward[live], step.obs[live],
                   step.terminated[live])

    evaluate(act, vec, config.demo_episodes, DEMO_SEED_BASE + config.seed, on_step=store)
    return buffer
