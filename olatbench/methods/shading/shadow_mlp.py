"""Θ_shad: refines the coarse light-view visibility v̂ into the shadow factor S(x) ∈ [0, 1].

A plain-torch stand-in for the official tiny-cuda-nn ``FullyFusedMLP``: ``num_hidden`` hidden layers of
``hidden`` units with LeakyReLU(0.01), a sigmoid output, Xavier-uniform weights; tiny-cuda-nn networks
have no biases, so only the first layer carries one (zero-initialised) to give the network an affine
input map. Inputs: frequency encodings (``num_freqs`` bands, sin/cos(2^k π x)) of the position and the
light direction, the coarse visibility and the material embedding. As in the official code the output
is ``relu(sigmoid(·) - 1e-5)`` so a fully shadowed Gaussian reaches exactly 0.
"""

from __future__ import annotations

import torch
from torch import nn

from olatbench.methods.shading.encoding import frequency_encoding, frequency_encoding_dim
from olatbench.methods.shading.precision import run_network


class ShadowNetwork(nn.Module):
    """``forward(positions (K,3), wi (K,3), coarse (K,1), material (K,M)) -> S (K, 1)``."""

    def __init__(self, material_dim: int = 6, hidden: int = 32, num_hidden: int = 3, num_freqs: int = 3,
                 precision: str = "fp32") -> None:
        super().__init__()
        self.num_freqs = num_freqs
        self.precision = precision  # of the layers (methods.shading.precision); inputs and output are float32
        in_dim = 2 * frequency_encoding_dim(3, num_freqs) + 1 + material_dim
        dims = [in_dim] + [hidden] * num_hidden + [1]
        self.layers = nn.ModuleList(
            nn.Linear(dims[i], dims[i + 1], bias=(i == 0)) for i in range(len(dims) - 1))
        for layer in self.layers:
            nn.init.xavier_uniform_(layer.weight)
            if layer.bias is not None:
                nn.init.zeros_(layer.bias)
        self.activation = nn.LeakyReLU(0.01)

    def forward(self, positions: torch.Tensor, wi: torch.Tensor, coarse: torch.Tensor,
                material: torch.Tensor) -> torch.Tensor:
        x = torch.cat([frequency_encoding(wi, self.num_freqs), frequency_encoding(positions, self.num_freqs),
                       material, coarse], dim=-1)
        return torch.relu(torch.sigmoid(run_network(self._body, x, self.precision)) - 1e-5)

    def _body(self, x: torch.Tensor) -> torch.Tensor:
        """The layers up to the output's pre-activation."""
        for layer in self.layers[:-1]:
            x = self.activation(layer(x))
        return self.layers[-1](x)
