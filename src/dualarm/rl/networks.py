"""Per-agent MLPs stored as one stacked tensor per layer, so both agents run in one bmm.

Agent ``i``'s weights are ``weight[i]``: a forward pass of both agents' networks is one
``torch.baddbmm`` per layer instead of two small matmuls, and Adam over the stacked
tensors is exactly two independent Adams (it is element-wise).
"""

from __future__ import annotations

import math

import torch
from torch import nn


class StackedLinear(nn.Module):
    """``num_agents`` independent affine maps: x (A, B, in) -> (A, B, out).

    Initialised like ``torch.nn.Linear`` (uniform in +-1/sqrt(in)) for each agent.
    """

    def __init__(self, num_agents: int, in_features: int, out_features: int,
                 generator: torch.Generator | None = None, init_scale: float = 1.0):
        super().__init__()
        bound = init_scale / math.sqrt(in_features)
        self.weight = nn.Parameter(
            (torch.rand(num_agents, in_features, out_features, generator=generator) * 2 - 1) * bound)
        self.bias = nn.Parameter(
            (torch.rand(num_agents, 1, out_features, generator=generator) * 2 - 1) * bound)

    def forward(self, x: torch.Tensor, stacks: int | None = None) -> torch.Tensor:
        """x (S, B, in) -> (S, B, out) through the first S maps (all when ``stacks`` is None)."""
        return torch.baddbmm(self.bias[:stacks], x, self.weight[:stacks])


class StackedLayerNorm(nn.Module):
    """Layer normalisation with a gain and bias per agent: x (A, B, width) -> same shape."""

    def __init__(self, num_agents: int, width: int):
        super().__init__()
        self.width = width
        self.gain = nn.Parameter(torch.ones(num_agents, 1, width))
        self.bias = nn.Parameter(torch.zeros(num_agents, 1, width))

    def forward(self, x: torch.Tensor, stacks: int | None = None) -> torch.Tensor:
        return torch.nn.functional.layer_norm(x, (self.width,)) * self.gain[:stacks] \
            + self.bias[:stacks]


class StackedMLP(nn.Module):
    """ReLU MLPs, one per agent: x (A, B, in) -> (A, B, out), optional tanh on the output.

    Args:
        num_agents: A.
        in_features, out_features: input and output widths (shared by the agents; pad
            narrower agents with zeros).
        hidden: widths of the hidden layers.
        tanh_output: squash the output to (-1, 1) (actors).
        generator: torch RNG for the initial weights (reproducible runs).
        final_scale: scale of the last layer's initial weights (small keeps early actions
            and values near zero).
        layer_norm: normalise every hidden layer's pre-activations over its width, with a
            learned per-agent gain and bias (Ba et al. 2016). In critics it bounds how far
            Q can extrapolate off the data (Ball et al. 2023), where an actor would chase it.
    """

    def __init__(self, num_agents: int, in_features: int, out_features: int,
                 hidden: tuple[int, ...], tanh_output: bool = False,
                 generator: torch.Generator | None = None, final_scale: float = 1.0,
                 layer_norm: bool = False):
        super().__init__()
        widths = (in_features, *hidden)
        self.hidden = nn.ModuleList(StackedLinear(num_agents, a, b, generator)
                                    for a, b in zip(widths[:-1], widths[1:]))
        self.norms = nn.ModuleList(StackedLayerNorm(num_agents, b) for b in hidden) \
            if layer_norm else None
        self.out = StackedLinear(num_agents, widths[-1], out_features, generator, final_scale)
        self.tanh_output = tanh_output

    def forward(self, x: torch.Tensor, stacks: int | None = None) -> torch.Tensor:
        """x (S, B, in) -> (S, B, out) through the first S networks (all if ``stacks`` is
        None): a caller that needs only some of the stacked networks pays only for those."""
        for k, layer in enumerate(self.hidden):
            x = layer(x, stacks)
            if self.norms is not None:
                x = self.norms[k](x, stacks)
            x = torch.relu(x)
        x = self.out(x, stacks)
        return torch.tanh(x) if self.tanh_output else x

    def flops_per_sample(self) -> int:
        """Multiply-adds x 2 of one forward pass of all agents for one sample."""
        total = 0
        for layer in (*self.hidden, self.out):
            a, i, o = layer.weight.shape
            total += 2 * a * i * o
        return total
