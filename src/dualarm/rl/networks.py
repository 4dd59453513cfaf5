"""Per-agent MLPs stored as one stacked tensor per layer, so both agents run in one bmm.

Agent ``i``'s weights are ``weight[i]``: a forward pass of both agents' networks is one
``torch.baddbmm`` per layer instead of two small matmuls, and Adam over the stacked
tensors is exactly two independent Adams (it is element-wise).

With ``low_precision`` the hidden layers compute in bfloat16 (mixed precision, as FastTD3's
``amp`` does on GPUs): the weights, their gradients and Adam stay float32, a layer's inputs,
weights and bias are rounded to bfloat16 (8 significant bits) for its product, and the hidden
activations stay bfloat16. The output layers compute in float32, so that values and actions
keep float32 precision. On a CPU with native bfloat16 arithmetic (AVX512-BF16 or AMX) an update
is about 1.5 times faster (docs/benchmarks.md); elsewhere torch emulates it, slower than float32.
"""

from __future__ import annotations

import math

import torch
from torch import nn


class StackedLinear(nn.Module):
    """``num_agents`` independent affine maps: x (A, B, in) -> (A, B, out).

    Initialised like ``torch.nn.Linear`` (uniform in +-1/sqrt(in)) for each agent. With
    ``low_precision`` x @ weight + bias is computed in bfloat16 and returned in bfloat16
    (float32 parameters); otherwise in float32 (x must be float32).
    """

    def __init__(self, num_agents: int, in_features: int, out_features: int,
                 generator: torch.Generator | None = None, init_scale: float = 1.0,
                 low_precision: bool = False):
        super().__init__()
        self.low_precision = low_precision
        bound = init_scale / math.sqrt(in_features)
        self.weight = nn.Parameter(
            (torch.rand(num_agents, in_features, out_features, generator=generator) * 2 - 1) * bound)
        self.bias = nn.Parameter(
            (torch.rand(num_agents, 1, out_features, generator=generator) * 2 - 1) * bound)

    def forward(self, x: torch.Tensor, stacks: int | None = None) -> torch.Tensor:
        """x (S, B, in) -> (S, B, out) through the first S maps (all when ``stacks`` is None)."""
        weight, bias = self.weight[:stacks], self.bias[:stacks]
        if self.low_precision:
            bf16 = torch.bfloat16
            return torch.baddbmm(bias.to(bf16), x.to(bf16), weight.to(bf16))
        return torch.baddbmm(bias, x, weight)


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
        low_precision: the hidden layers' products in bfloat16 (the output layer's stay
            float32); see the module's docstring.
    """

    def __init__(self, num_agents: int, in_features: int, out_features: int,
                 hidden: tuple[int, ...], tanh_output: bool = False,
                 generator: torch.Generator | None = None, final_scale: float = 1.0,
                 low_precision: bool = False):
        super().__init__()
        widths = (in_features, *hidden)
        self.hidden = nn.ModuleList(StackedLinear(num_agents, a, b, generator, low_precision=low_precision)
                                    for a, b in zip(widths[:-1], widths[1:]))
        self.out = StackedLinear(num_agents, widths[-1], out_features, generator, final_scale)
        self.tanh_output = tanh_output
        self.low_precision = low_precision

    def forward(self, x: torch.Tensor, stacks: int | None = None) -> torch.Tensor:
        """x (S, B, in) -> (S, B, out) through the first S networks (all if ``stacks`` is
        None): a caller that needs only some of the stacked networks pays only for those."""
        for layer in self.hidden:
            x = torch.relu(layer(x, stacks))
        if self.low_precision:                  # bfloat16 activations into the float32 output layer
            x = x.float()
        x = self.out(x, stacks)
        return torch.tanh(x) if self.tanh_output else x

    def flops_per_sample(self) -> int:
        """Multiply-adds x 2 of one forward pass of all agents for one sample."""
        total = 0
        for layer in (*self.hidden, self.out):
            a, i, o = layer.weight.shape
            total += 2 * a * i * o
        return total
