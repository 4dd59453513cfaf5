"""A ring buffer of joint transitions (both agents' observations, actions and rewards)."""

from __future__ import annotations

import numpy as np
import torch

_FIELDS = ("obs", "act", "rew", "next_obs", "done", "left")


class ReplayBuffer:
    """Transitions of a two-agent (or A-agent) environment, stored as float32 arrays.

    Shapes: obs and next_obs (capacity, A, obs_size), act (capacity, A, act_size),
    rew (capacity, A), done (capacity,) 1.0 where the episode terminated (not truncated:
    a time limit is not a terminal state, so it still bootstraps), left (capacity,) how many transitions of the same episode follow this one in storage
    (hindsight relabelling draws its future goals from them; 0 when episodes are not stored
    whole).
    """

    def __init__(self, capacity: int, num_agents: int, obs_size: int, act_size: int):
        self.capacity = int(capacity)
        self.shapes = {"obs": (num_agents, obs_size), "act": (num_agents, act_size),
                       "rew": (num_agents,), "next_obs": (num_agents, obs_size), "done": (),
                       "left": ()}
        # np.empty of a large capacity reserves address space only: pages fill as we write.
        self.data = {k: np.empty((self.capacity, *s), dtype=np.float32) for k, s in self.shapes.items()}
        self.size = 0
        self.next = 0

    def __len__(self) -> int:
        return self.size

    def add(self, obs, act, rew, next_obs, done, left=0) -> None:
        """Append N transitions (leading axis N on every argument; ``left`` may be a scalar)."""
        n = len(obs)
        idx = (self.next + np.arange(n)) % self.capacity
        for key, value in zip(_FIELDS, (obs, act, rew, next_obs, done, left)):
            self.data[key][idx] = value
        self.next = int((self.next + n) % self.capacity)
        self.size = min(self.size + n, self.capacity)

    def sample(self, rng: np.random.Generator, batch_size: int) -> dict[str, torch.Tensor]:
        """A uniform batch (with replacement) as float32 tensors with a leading batch axis."""
        idx = rng.integers(0, self.size, size=batch_size)
        return {k: torch.from_numpy(v[idx]) for k, v in self.data.items()}

    def add_episode(self, obs, act, rew, next_obs, terminated: bool) -> None:
        """Append one finished episode of T one-step transitions, in order, so that each
        transition knows the ``left`` transitions that follow it."""
        t_len = len(obs)
        done = np.zeros(t_len, dtype=np.float32)
        done[-1] = float(terminated)
        self.add(obs, act, rew, next_obs, done, np.arange(t_len - 1, -1, -1))

    def state_dict(self) -> dict:
        """The filled rows as tensors, in storage order, and the write position (a checkpoint
        stores only what is there; sampling after a reload draws the same transitions)."""
        return {"capacity": self.capacity, "size": self.size, "next": self.next,
                **{k: torch.from_numpy(v[:self.size].copy()) for k, v in self.data.items()}}

    def load_state_dict(self, state: dict) -> None:
        size = int(state["size"])
        if size > self.capacity:
            raise ValueError(f"the saved replay buffer holds {size} transitions, more than "
                             f"this buffer's capacity {self.capacity}")
        for k, shape in self.shapes.items():
            if k == "left" and k not in state:     # checkpoints from before the field
                self.data[k][:size] = 0.0
                continue
            saved = state[k]
            if tuple(saved.shape[1:]) != shape:
                raise ValueError(f"replay field {k!r} has shape {tuple(saved.shape[1:])} per "
                                 f"transition, expected {shape}")
            self.data[k][:size] = saved.numpy()
        self.size = size
        self.next = int(state["next"]) % self.capacity
