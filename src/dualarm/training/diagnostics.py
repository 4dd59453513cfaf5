"""Why a learner fails: its critics' values next to the returns its policy really collects.

``critic_vs_returns`` runs seeded episodes with the deterministic policy, records every
transition, and compares each agent's critic Q_i(s_t, a_t,i) with the discounted return
actually observed from that step on. A critic that rates the policy far above what it
collects (over-estimation) is what lets a DDPG actor climb into actions that pay nothing
(Fujimoto et al. 2018). ``replay_composition`` says what fills the replay buffer: how many
transitions carry each of the task's bonuses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from dualarm.training.evaluation import evaluate
from dualarm.training.vector import EVAL_SEED_BASE, VectorEnv


@dataclass
class CriticReport:
    """Critic values against observed returns, per agent (all in the critic's reward units,
    i.e. raw rewards times ``reward_scale``).

    Attributes:
        q_mean: (A,) mean over all visited steps of Q_i(s_t, a_t,i).
        return_mean: (A,) mean over the same steps of the observed return from t, bootstrapped
            at a time limit with the target critic's own value of the last state (as Eq. 13
            does), so that both sides estimate the same quantity.
        q_first: (A,) mean Q at the first step of the episodes.
        return_first: (A,) mean observed return from the first step.
        bias: (A,) q_mean - return_mean: > 0 is over-estimation.
        steps: transitions compared.
        q_by_step, return_by_step: (S, A) means over the episodes still running at step t,
            t = 0..S-1 (S the longest episode): where in an episode the critic is wrong.
        episodes_by_step: (S,) how many episodes each of those means is over.
    """

    q_mean: np.ndarray
    return_mean: np.ndarray
    q_first: np.ndarray
    return_first: np.ndarray
    bias: np.ndarray
    steps: int
    q_by_step: np.ndarray | None = None
    return_by_step: np.ndarray | None = None
    episodes_by_step: np.ndarray | None = None

    def as_row(self) -> dict:
        """Flat dict for a CSV row (agents 0, 1 as suffixes)."""
        row = {"steps": self.steps}
        for name in ("q_mean", "return_mean", "q_first", "return_first", "bias"):
            for i, v in enumerate(getattr(self, name)):
                row[f"{name}_{i}"] = round(float(v), 5)
        return row


def discounted_returns(rewards: np.ndarray, gamma: float, tail: np.ndarray | float = 0.0) -> np.ndarray:
    """Returns-to-go G_t = sum_k gamma^k r_{t+k} + gamma^(T-t) tail for rewards (T, A)."""
    out = np.zeros_like(rewards, dtype=float)
    g = np.asarray(tail, dtype=float) * np.ones(rewards.shape[1:])
    for t in range(len(rewards) - 1, -1, -1):
        g = rewards[t] + gamma * g
        out[t] = g
    return out


def _q_values(agent, obs: np.ndarray, actions: np.ndarray) -> np.ndarray:
    """First critic of each agent: obs (T, A, O), actions (T, A, U) -> Q (T, A)."""
    with torch.inference_mode():
        o = agent.normalizer.normalize(torch.as_tensor(obs, dtype=torch.float32)).transpose(0, 1)
        a = torch.as_tensor(actions, dtype=torch.float32).transpose(0, 1)
        q = agent._per_agent(agent.critic(agent._critic_input(o, a)))[0]  # (A, T, 1)
    return q[..., 0].t().numpy().astype(float)


def _target_value(agent, obs: np.ndarray) -> np.ndarray:
    """min over twins of Q'_i(s, mu'_i(s_i)) for obs (T, A, O) -> (T, A)."""
    with torch.inference_mode():
        o = agent.normalizer.normalize(torch.as_tensor(obs, dtype=torch.float32)).transpose(0, 1)
        a = agent.actor_target(o) * agent.action_mask
        q = agent._per_agent(agent.critic_target(agent._critic_input(o, a))).min(dim=0).values
    return q[..., 0].t().numpy().astype(float)


def critic_vs_returns(agent, vec: VectorEnv, episodes: int = 16,
                      seed_base: int = EVAL_SEED_BASE, potential=None) -> CriticReport:
    """Compare the critics with the observed returns of ``episodes`` deterministic episodes.

    Args:
        agent: a ``DADDPG`` learner with its trained critics (``policy.load_learner``).
        vec: environment copies (the run's evaluation copies will do).
        episodes: how many episodes (the evaluation's seeds by default).
        potential: for a run trained with potential-based shaping, phi: raw observations
            (T, A, O) -> (T, A) in the critic's units; the returns then add
            gamma * phi(s') * (1 - done) - phi(s) per step, as the learner's targets do.
    """
    gamma, scale = agent.config.gamma, agent.config.reward_scale
    per_env: dict[int, list] = {}
    finished: list[list] = []

    def record(obs, actions, step, live):
        for i in live:
            per_env.setdefault(int(i), []).append(
                (obs[i].copy(), actions[i].copy(), step.reward[i] * scale, step.obs[i].copy(),
                 bool(step.terminated[i]), bool(step.truncated[i])))
            if step.terminated[i] or step.truncated[i]:
                finished.append(per_env.pop(int(i)))

    evaluate(lambda o: agent.act(o), vec, episodes, seed_base, on_step=record)
    qs, gs, q0, g0 = [], [], [], []
    for ep in finished:
        obs, act, rew, next_obs, term, trunc = (np.stack(x) for x in zip(*ep))
        if potential is not None:
            rew = rew + gamma * (1.0 - term[:, None]) * potential(next_obs) - potential(obs)
        tail = 0.0 if term[-1] else _target_value(agent, next_obs[-1:])[0]
        g = discounted_returns(rew, gamma, tail)
        q = _q_values(agent, obs, act)
        qs.append(q)
        gs.append(g)
        q0.append(q[0])
        g0.append(g[0])
    q_all, g_all = np.concatenate(qs), np.concatenate(gs)
    longest = max(len(q) for q in qs)
    count = np.array([sum(len(q) > t for q in qs) for t in range(longest)])
    by_step = [np.stack([np.pad(x, ((0, longest - len(x)), (0, 0))) for x in xs]).sum(0)
               / count[:, None] for xs in (qs, gs)]
    return CriticReport(q_all.mean(0), g_all.mean(0), np.mean(q0, 0), np.mean(g0, 0),
                        q_all.mean(0) - g_all.mean(0), len(q_all), *by_step, count)


def replay_composition(buffer, thresholds: dict[str, float]) -> dict[str, float]:
    """Fraction of the replay buffer's transitions whose reward (raw, any agent) exceeds each
    threshold, e.g. ``{"reach_bonus": 0.5, "grasp_bonus": 10, "success": 1000}``."""
    n = len(buffer)
    if n == 0:
        return {name: 0.0 for name in thresholds}
    rew = buffer.data["rew"][:n]
    return {name: float((rew > t).any(axis=1).mean()) for name, t in thresholds.items()}
