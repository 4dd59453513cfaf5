"""Both actors of a run as one ONNX model, the observation normaliser folded in.

Inputs ``obs_left`` (B, O_left) and ``obs_right`` (B, O_right), raw observations as the
environment gives them (float32); outputs ``action_left`` (B, U_left) and ``action_right``
(B, U_right) in [-1, 1], the deterministic policy (no exploration noise). B is dynamic.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch import nn

from dualarm.atomic import atomic_open
from dualarm.rl.daddpg import DADDPG

INPUT_NAMES = ("obs_left", "obs_right")
OUTPUT_NAMES = ("action_left", "action_right")


class FoldedPolicy(nn.Module):
    """mu_i((obs_i - mean_i) / std_i clipped) for the two agents, as plain matmuls (no
    stacked baddbmm, no running statistics): what the ONNX file holds."""

    def __init__(self, agent: DADDPG):
        super().__init__()
        self.obs_sizes, self.act_sizes = tuple(agent.obs_sizes), tuple(agent.act_sizes)
        norm = agent.normalizer
        self.clip = float(norm.clip)
        self.register_buffer("mean", norm.mean.detach().clone().float())      # (2, O)
        self.register_buffer("std", norm.std.detach().clone().float())
        layers = [*agent.actor.hidden, agent.actor.out]
        self.weights = nn.ParameterList(nn.Parameter(l.weight.detach().clone(), requires_grad=False)
                                        for l in layers)                        # (2, in, out)
        self.biases = nn.ParameterList(nn.Parameter(l.bias.detach().clone()[:, 0], requires_grad=False)
                                       for l in layers)                         # (2, out)

    def _actor(self, i: int, obs: torch.Tensor) -> torch.Tensor:
        o = self.obs_sizes[i]
        x = torch.clamp((obs - self.mean[i, :o]) / self.std[i, :o], -self.clip, self.clip)
        last = len(self.weights) - 1
        for k, (w, b) in enumerate(zip(self.weights, self.biases)):
            w_i = w[i, :o] if k == 0 else w[i]          # narrower agents: zero-padded inputs
            x = x @ w_i + b[i]
            x = torch.tanh(x) if k == last else torch.relu(x)
        return x[:, :self.act_sizes[i]]

    def forward(self, obs_left: torch.Tensor, obs_right: torch.Tensor):
        return self._actor(0, obs_left), self._actor(1, obs_right)


def export_onnx(agent: DADDPG, path: str | Path) -> None:
    """Write the run's policy as ONNX (opset of torch's exporter), atomically."""
    import logging
    import warnings

    logging.getLogger("torch.onnx._internal.exporter._registration").setLevel(logging.ERROR)
    model = FoldedPolicy(agent).eval()
    example = tuple(torch.zeros(2, n) for n in model.obs_sizes)
    batch = torch.export.Dim("batch")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                 # the exporter's notes on axis names
        program = torch.onnx.export(model, example, input_names=list(INPUT_NAMES),
                                    output_names=list(OUTPUT_NAMES),
                                    dynamic_shapes=({0: batch}, {0: batch}), dynamo=True,
                                    verbose=False)
    with atomic_open(path) as f:
        f.write(program.model_proto.SerializeToString())


def onnx_actions(path: str | Path, obs: np.ndarray) -> np.ndarray:
    """Actions (N, 2, U) from the ONNX file for observations (N, 2, O) (onnxruntime)."""
    import onnxruntime

    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    sizes = [i.shape[1] for i in session.get_inputs()]
    feed = {name: np.ascontiguousarray(obs[:, k, :sizes[k]], dtype=np.float32)
            for k, name in enumerate(INPUT_NAMES)}
    left, right = session.run(list(OUTPUT_NAMES), feed)
    out = np.zeros((len(obs), 2, max(left.shape[1], right.shape[1])), dtype=np.float32)
    out[:, 0, :left.shape[1]], out[:, 1, :right.shape[1]] = left, right
    return out


def check_onnx(agent: DADDPG, path: str | Path, config, observations: int = 1000) -> dict:
    """Compare the ONNX file with PyTorch on ``observations`` observations that the policy
    meets in its own task (episodes from the evaluation placements, deterministic policy).

    Returns:
        {"observations": how many, "max_abs": largest |difference| of any action}.
    """
    from dualarm.training.vector import make_vector_env
    from dualarm.training.rounds import run_round
    from dualarm.training.vector import EVAL_SEED_BASE, seeds_for

    vec = make_vector_env(config, 16)
    seen: list[np.ndarray] = []
    act = lambda o: agent.act(o)        # noqa: E731
    first = 0
    while sum(len(x) for x in seen) < observations:
        run_round(vec, seeds_for(EVAL_SEED_BASE, first, vec.num_envs), act,
                  lambda obs, a, step, live: seen.append(obs[live]))
        first += vec.num_envs
    vec.close()
    obs = np.concatenate(seen)[:observations]
    ours = agent.act(obs)
    theirs = onnx_actions(path, obs)
    return {"observations": len(obs), "max_abs": float(np.abs(ours - theirs).max())}
