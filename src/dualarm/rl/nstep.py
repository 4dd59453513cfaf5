"""n-step transitions of one finished episode: rewards summed over up to n steps."""

from __future__ import annotations

import numpy as np


def nstep_episode(obs: np.ndarray, act: np.ndarray, rew: np.ndarray, next_obs: np.ndarray,
                  terminated: bool, n: int, gamma: float) -> tuple[np.ndarray, ...]:
    """The n-step transitions of an episode of T steps, one per step t.

    Transition t spans m = min(n, T - t) steps: its reward is sum_{k<m} gamma^k r_{t+k}, its
    next observation the one after step t + m - 1, and it is terminal only if that step
    ended the episode by termination (a truncated episode still bootstraps, with gamma^m).

    Args:
        obs, next_obs: (T, A, O) observations before and after each step.
        act: (T, A, U) actions taken.
        rew: (T, A) rewards, or (T, A, H) reward components (summed component-wise).
        terminated: the last step terminated the episode (success or failure, not a time limit).
        n: steps per transition (n >= 1; n = 1 returns the one-step transitions).
        gamma: discount per step.

    Returns:
        (obs (T, A, O), act (T, A, U), rew (T, A), next_obs (T, A, O), done (T,), steps (T,)).
    """
    t_len = len(rew)
    t = np.arange(t_len)
    last = np.minimum(t + n, t_len) - 1                 # last step of each transition
    summed = np.zeros_like(rew, dtype=np.float64)
    for k in range(n):
        inside = t + k < t_len
        summed[inside] += gamma ** k * rew[t[inside] + k]
    done = np.zeros(t_len, dtype=np.float32)
    done[last == t_len - 1] = float(terminated)
    steps = (last - t + 1).astype(np.float32)
    return obs, act, summed, next_obs[last], done, steps
