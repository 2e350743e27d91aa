"""Subsurface scattering: the standard dipole profile (Jensen et al. 2001) with per-Gaussian
parameters predicted by an MLP.

Dipole (η = 1.3 by default; lengths in scene units, coefficients in 1/scene units)::

    F_dr = -1.440/η² + 0.710/η + 0.668 + 0.0636 η          A = (1 + F_dr) / (1 - F_dr)
    σ_t' = σ_s + σ_a     α' = σ_s / σ_t'    σ_tr = sqrt(3 σ_a σ_t')
    z_r = 1/σ_t'         z_v = z_r (1 + 4A/3)
    d_r = sqrt(r² + z_r²)   d_v = sqrt(r² + z_v²)
    R_d(r) = α'/(4π) [ z_r (σ_tr d_r + 1) e^{-σ_tr d_r} / d_r³
                     + k_v (σ_tr d_v + 1) e^{-σ_tr d_v} / d_v³ ]

with ``k_v = z_v`` (``"jensen"``, default) or ``k_v = z_r z_v`` (``"official"``: the factor in the
paper's Eq. 4 and the official code). The exponent uses the effective transport coefficient σ_tr, as
in Jensen et al. and the official code (the paper's Eq. 4 writes σ_t).
"""

from __future__ import annotations

import math
from typing import Literal

import torch
from torch import nn
from torch.utils.checkpoint import checkpoint

from olatbench.methods.shading.encoding import positional_encoding, positional_encoding_dim
from olatbench.methods.shading.mlp import mlp
from olatbench.methods.shading.precision import run_network

VirtualFactor = Literal["jensen", "official"]

# Batches above this many Gaussians run the MLP in chunks of this size under activation
# checkpointing when a graph is being built: the hidden activations of one chunk (≈ 0.4 GB at the
# paper's 256×6 network) are kept instead of the whole batch's (≈ 3.4 GB at 550K Gaussians);
# backward recomputes each chunk's forward once (≈ +30 % MLP time, only on such batches). Smaller
# batches — every mini run — take the plain path.
CHECKPOINT_ROWS = 65_536

SIGMA_RANGE = (0.05, 2.05)  # σ_s and σ_a after sigmoid rescaling
RADIUS_RANGE = (0.1, 3.1)  # r after sigmoid rescaling


def diffuse_reflectance_fresnel(eta: float) -> float:
    """Jensen's fit of the average diffuse Fresnel reflectance F_dr(η)."""
    return -1.440 / eta**2 + 0.710 / eta + 0.668 + 0.0636 * eta


def dipole_profile(
    r: torch.Tensor,
    sigma_s: torch.Tensor,
    sigma_a: torch.Tensor,
    eta: float = 1.3,
    virtual_factor: VirtualFactor = "jensen",
) -> torch.Tensor:
    """Dipole diffuse reflectance R_d at separation ``r``; all inputs broadcast, output has their
    shape."""
    f_dr = diffuse_reflectance_fresnel(eta)
    a = (1.0 + f_dr) / (1.0 - f_dr)
    sigma_t = sigma_s + sigma_a
    albedo = sigma_s / sigma_t
    sigma_tr = torch.sqrt(3.0 * sigma_a * sigma_t)
    z_r = 1.0 / sigma_t
    z_v = z_r * (1.0 + 4.0 * a / 3.0)
    d_r = torch.sqrt(r * r + z_r * z_r)
    d_v = torch.sqrt(r * r + z_v * z_v)
    if virtual_factor == "jensen":
        k_v = z_v
    elif virtual_factor == "official":
        k_v = z_r * z_v
    else:
        raise ValueError(
            f"dipole_virtual_factor must be 'jensen' or 'official', not {virtual_factor!r}"
        )
    real = z_r * (sigma_tr * d_r + 1.0) * torch.exp(-sigma_tr * d_r) / d_r**3
    virtual = k_v * (sigma_tr * d_v + 1.0) * torch.exp(-sigma_tr * d_v) / d_v**3
    return albedo * (real + virtual) / (4.0 * math.pi)


class SSSNetwork(nn.Module):
    """Θ_SSS: (x, ωo, ωi, n, m) -> (σ_s, σ_a, r) -> dipole profile f_sss (K, 1).

    Inputs: positions, view and light directions positionally encoded with ``num_freqs`` bands, the
    normal and the per-Gaussian material embedding (``material_dim``). ``num_linear`` counts Linear
    layers (the paper's "6 layers"; the official code uses 5 with a 128-wide last hidden layer:
    ``last_hidden``).
    """

    def __init__(
        self,
        material_dim: int = 6,
        hidden: int = 256,
        num_linear: int = 6,
        num_freqs: int = 4,
        eta: float = 1.3,
        virtual_factor: VirtualFactor = "jensen",
        precision: str = "fp32",
        last_hidden: int | None = None,
    ) -> None:
        super().__init__()
        self.num_freqs = num_freqs
        # of the MLP (methods.shading.precision); inputs and output are float32
        self.precision = precision
        self.eta = eta
        self.virtual_factor = virtual_factor
        in_dim = 3 * positional_encoding_dim(3, num_freqs) + 3 + material_dim
        self.network = mlp(in_dim, hidden, 3, num_linear, last_hidden)

    def encode(
        self,
        positions: torch.Tensor,
        wo: torch.Tensor,
        wi: torch.Tensor,
        normals: torch.Tensor,
        material: torch.Tensor,
    ) -> torch.Tensor:
        """The network input (K, in_dim)."""
        return torch.cat(
            [
                positional_encoding(wi, self.num_freqs),
                positional_encoding(wo, self.num_freqs),
                positional_encoding(positions, self.num_freqs),
                normals,
                material,
            ],
            dim=-1,
        )

    def parameters_from_input(
        self, encoded: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(σ_s, σ_a, r), each (K, 1), from the encoded input (chunked and checkpointed above
        `CHECKPOINT_ROWS` rows while building a graph)."""
        if torch.is_grad_enabled() and encoded.shape[0] > CHECKPOINT_ROWS:
            out = torch.cat(
                [
                    checkpoint(self._network, chunk, use_reentrant=False)
                    for chunk in encoded.split(CHECKPOINT_ROWS)
                ]
            )
        else:
            out = self._network(encoded)
        raw = torch.sigmoid(out)
        low, high = SIGMA_RANGE
        sigma_s = low + (high - low) * raw[:, 0:1]
        sigma_a = low + (high - low) * raw[:, 1:2]
        r = RADIUS_RANGE[0] + (RADIUS_RANGE[1] - RADIUS_RANGE[0]) * raw[:, 2:3]
        return sigma_s, sigma_a, r

    def _network(self, encoded: torch.Tensor) -> torch.Tensor:
        """The MLP at ``precision`` (float32 output)."""
        return run_network(self.network, encoded, self.precision)

    def forward(
        self,
        positions: torch.Tensor,
        wo: torch.Tensor,
        wi: torch.Tensor,
        normals: torch.Tensor,
        material: torch.Tensor,
    ) -> torch.Tensor:
        """f_sss (K, 1) for K Gaussians (all inputs (K, ·))."""
        sigma_s, sigma_a, r = self.parameters_from_input(
            self.encode(positions, wo, wi, normals, material)
        )
        return dipole_profile(r, sigma_s, sigma_a, self.eta, self.virtual_factor)
