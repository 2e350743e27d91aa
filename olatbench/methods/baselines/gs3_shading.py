"""Per-Gaussian shading of GS³ (Bi et al. 2024) built from the shared blocks of
`olatbench.methods.shading`.

For K visible Gaussians (directions point away from the Gaussian: ``wi`` to the light, ``wo`` to the
camera)::

    I = (k_d / π + k_s · D_ASG(h) · F(ωi·h)) · cos⁺(n, ωi) · L / d²   (the cosine multiplies both)
    V = Θ_shadow(ωi, x, m, v̂)   v̂: the light-view visibility hint (`olatbench.gaussians.shadow`)
    O = 2 · sigmoid(Θ_other(ωo, x, m)) · L / d²

k_d, k_s are softplus colours, D_ASG the official GS³ mixture of angular Gaussians
(`ASGMixture` with ``form="official"``), F Schlick's Fresnel with F0 = 0.04, the cosine the official
smooth clamp, and the shading frame (normal = its z axis) a learned per-Gaussian quaternion
``shading_quat``. Θ_shadow is the `ShadowNetwork` SSD-GS uses too (same inputs and output activation
as GS³'s shadow head); Θ_other is an MLP on the frequency encodings of ωo and x and the material
embedding m (GS³: 3 hidden layers of 128).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from olatbench.gaussians.projection import quat_to_rotmat
from olatbench.methods.shading.asg import ASGMixture
from olatbench.methods.shading.encoding import frequency_encoding, frequency_encoding_dim
from olatbench.methods.shading.mlp import mlp
from olatbench.methods.shading.precision import run_network
from olatbench.methods.shading.shadow_mlp import ShadowNetwork, ones_padding, padded_input
from olatbench.methods.shading.terms import (
    inverse_square_irradiance,
    lambert_cosine,
    safe_normalize,
    schlick_fresnel,
)

NETWORK_LAYOUTS = ("torch", "tiny_cuda_nn")


class OtherEffectsNetwork(nn.Module):
    """Θ_other: ``forward(wo (K,3), positions (K,3), material (K,M)) -> (K, 3)`` in [0, 2].
    ``layout``: "torch", a plain MLP (ReLU, a bias in every layer); "tiny_cuda_nn", the authors'
    FullyFusedMLP (LeakyReLU(0.01), no biases, the input padded with ones to a multiple of 16 whose
    weights act as the first layer's bias: `olatbench.methods.shading.shadow_mlp`)."""

    def __init__(
        self,
        material_dim: int = 6,
        hidden: int = 128,
        num_hidden: int = 3,
        num_freqs: int = 4,
        precision: str = "fp32",
        layout: str = "torch",
    ) -> None:
        super().__init__()
        if layout not in NETWORK_LAYOUTS:
            raise ValueError(
                f"other-effects network layout must be one of {NETWORK_LAYOUTS}, not {layout!r}"
            )
        self.num_freqs = num_freqs
        # of the MLP (methods.shading.precision); inputs and output are float32
        self.precision = precision
        in_dim = 2 * frequency_encoding_dim(3, num_freqs) + material_dim
        self.padding = ones_padding(in_dim) if layout == "tiny_cuda_nn" else 0
        if layout == "torch":
            self.network = mlp(in_dim, hidden, 3, num_hidden + 1)
        else:
            widths = [in_dim + self.padding] + [hidden] * num_hidden
            layers: list[nn.Module] = []
            for width_in, width_out in itertools.pairwise(widths):
                layers += [nn.Linear(width_in, width_out, bias=False), nn.LeakyReLU(0.01)]
            layers.append(nn.Linear(hidden, 3, bias=False))
            self.network = nn.Sequential(*layers)

    def forward(
        self, wo: torch.Tensor, positions: torch.Tensor, material: torch.Tensor
    ) -> torch.Tensor:
        parts = [
            frequency_encoding(wo, self.num_freqs),
            frequency_encoding(positions, self.num_freqs),
            material,
        ]
        x = padded_input(parts, self.padding)
        return 2.0 * torch.sigmoid(run_network(self.network, x, self.precision))


@dataclass
class GS3Components:
    """Per-Gaussian terms (K, ·), all including ``L / d²`` where they are radiance: ``diffuse`` (3)
    and ``specular`` (3) with the cosine, ``visibility`` V (1), ``hint`` v̂ (1), ``other`` O (3)."""

    diffuse: torch.Tensor
    specular: torch.Tensor
    visibility: torch.Tensor
    hint: torch.Tensor
    other: torch.Tensor

    @property
    def shading(self) -> torch.Tensor:
        """I = diffuse + specular (K, 3)."""
        return self.diffuse + self.specular


class GS3Shader(nn.Module):
    """The global learnable parts of GS³ (ASG lobes, shadow and other-effects networks) and its
    shading."""

    def __init__(
        self,
        num_asg: int = 8,
        material_dim: int = 6,
        shadow_hidden: int = 32,
        shadow_layers: int = 3,
        other_hidden: int = 128,
        other_layers: int = 3,
        num_freqs: int = 4,
        fresnel_f0: float = 0.04,
        precision: str = "fp32",
        other_scale: float = 1.0,
        network_layout: str = "torch",
    ) -> None:
        super().__init__()
        self.fresnel_f0 = fresnel_f0
        # O = other_net · other_scale · L/d² (1: official; GS3 sets it per scene)
        self.other_scale = other_scale
        self.asg = ASGMixture(num_asg, form="official")
        shadow_bias = "padded_ones" if network_layout == "tiny_cuda_nn" else "vector"
        self.shadow_net = ShadowNetwork(
            material_dim, shadow_hidden, shadow_layers, num_freqs, precision, shadow_bias
        )
        self.other_net = OtherEffectsNetwork(
            material_dim, other_hidden, other_layers, num_freqs, precision, network_layout
        )

    def forward(
        self,
        positions: torch.Tensor,
        attributes: dict[str, torch.Tensor],
        camera_position: torch.Tensor,
        light_position: torch.Tensor,
        intensity: torch.Tensor,
        specular: bool,
        hint: torch.Tensor | None,
    ) -> GS3Components:
        """Shade K Gaussians. ``specular`` switches the specular term on; with ``hint`` (K,) given,
        V and O come from the networks, otherwise V = 1 and O = 0 (GS³'s diffuse warm-up)."""
        wi, incident = inverse_square_irradiance(positions, light_position, intensity)
        wo = safe_normalize(camera_position[None, :] - positions)
        frames = quat_to_rotmat(attributes["shading_quat"])  # columns x, y, z = normal
        cosine = lambert_cosine(frames[:, :, 2], wi, "smooth")
        diffuse = F.softplus(attributes["diffuse"]) / math.pi * cosine * incident
        if specular:
            half = safe_normalize(wi + wo)
            h_local = torch.einsum("ki,kij->kj", half, frames)
            lobes = self.asg(h_local, F.softplus(attributes["asg_weights"]))
            fresnel = schlick_fresnel(wi, half, self.fresnel_f0)
            specular_term = F.softplus(attributes["specular"]) * lobes * fresnel * cosine * incident
        else:
            specular_term = torch.zeros_like(diffuse)
        ones = positions.new_ones(positions.shape[0], 1)
        if hint is None:
            return GS3Components(diffuse, specular_term, ones, ones, torch.zeros_like(diffuse))
        material = attributes["material"]
        hint = hint[:, None].to(positions.dtype)
        visibility = self.shadow_net(positions, wi, hint, material)
        other = self.other_net(wo, positions, material) * (self.other_scale * incident)
        return GS3Components(diffuse, specular_term, visibility, hint, other)


__all__ = ["GS3Components", "GS3Shader", "OtherEffectsNetwork"]
