"""Θ_shad: refines the coarse light-view visibility v̂ into the shadow factor S(x) ∈ [0, 1].

A plain-torch stand-in for the official tiny-cuda-nn ``FullyFusedMLP``: ``num_hidden`` hidden layers
of ``hidden`` units with LeakyReLU(0.01), a sigmoid output, Xavier-uniform weights. tiny-cuda-nn
networks have no biases; the first layer's affine input map comes from ``input_bias``:

* ``"vector"`` (default): the first layer carries one bias vector (zero-initialised);
* ``"padded_ones"``: tiny-cuda-nn's own layout — the input is padded with ones to a multiple of 16
  columns (its Identity encoding, `olatbench.methods.official.cpu_standins.tcnn`) and the first
  layer has no bias, so the padded columns' weights act as the bias. The function is the same as a
  bias equal to their sum, but each of those weights is a parameter of its own: Adam moves the sum
  by up to (number of padded columns) × its rate per step where a bias vector moves by one rate (the
  authors' code: 9 columns at 4 frequencies).

Inputs: frequency encodings (``num_freqs`` bands, sin/cos(2^k π x)) of the position and the light
direction, the coarse visibility and the material embedding. As in the official code the output is
``relu(sigmoid(·) - 1e-5)`` so a fully shadowed Gaussian reaches exactly 0.
"""

from __future__ import annotations

import torch
from torch import nn

from olatbench.methods.shading.encoding import frequency_encoding, frequency_encoding_dim
from olatbench.methods.shading.precision import run_network

INPUT_BIASES = ("vector", "padded_ones")
PADDING = 16  # tiny-cuda-nn's FullyFusedMLP pads its input width to a multiple of this


def ones_padding(width: int) -> int:
    """The constant-one columns tiny-cuda-nn's FullyFusedMLP appends to an input ``width`` columns
    wide: up to the next multiple of `PADDING`."""
    return -width % PADDING


def padded_input(parts: list[torch.Tensor], padding: int) -> torch.Tensor:
    """``parts`` (each (K, ·)) side by side, then ``padding`` columns of ones: (K, Σ + padding)."""
    if padding:
        parts = [*parts, parts[0].new_ones(parts[0].shape[0], padding)]
    return torch.cat(parts, dim=-1)


class ShadowNetwork(nn.Module):
    """``forward(positions (K,3), wi (K,3), coarse (K,1), material (K,M)) -> S (K, 1)``;
    ``input_bias`` as in the module docstring."""

    def __init__(
        self,
        material_dim: int = 6,
        hidden: int = 32,
        num_hidden: int = 3,
        num_freqs: int = 3,
        precision: str = "fp32",
        input_bias: str = "vector",
    ) -> None:
        super().__init__()
        if input_bias not in INPUT_BIASES:
            raise ValueError(
                f"shadow network input_bias must be one of {INPUT_BIASES}, not {input_bias!r}"
            )
        self.num_freqs = num_freqs
        # of the layers (methods.shading.precision); inputs and output are float32
        self.precision = precision
        self.in_dim = 2 * frequency_encoding_dim(3, num_freqs) + 1 + material_dim
        padded = input_bias == "padded_ones"
        # constant-one columns appended to the input
        self.padding = ones_padding(self.in_dim) if padded else 0
        dims = [self.in_dim + self.padding] + [hidden] * num_hidden + [1]
        self.layers = nn.ModuleList(
            nn.Linear(dims[i], dims[i + 1], bias=(i == 0 and not padded))
            for i in range(len(dims) - 1)
        )
        for layer in self.layers:
            nn.init.xavier_uniform_(layer.weight)
            if layer.bias is not None:
                nn.init.zeros_(layer.bias)
        self.activation = nn.LeakyReLU(0.01)

    def forward(
        self,
        positions: torch.Tensor,
        wi: torch.Tensor,
        coarse: torch.Tensor,
        material: torch.Tensor,
    ) -> torch.Tensor:
        parts = [
            frequency_encoding(wi, self.num_freqs),
            frequency_encoding(positions, self.num_freqs),
            material,
            coarse,
        ]
        x = padded_input(parts, self.padding)
        return torch.relu(torch.sigmoid(run_network(self._body, x, self.precision)) - 1e-5)

    def _body(self, x: torch.Tensor) -> torch.Tensor:
        """The layers up to the output's pre-activation."""
        for layer in self.layers[:-1]:
            x = self.activation(layer(x))
        return self.layers[-1](x)
