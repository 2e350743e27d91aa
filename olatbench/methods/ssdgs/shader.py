"""Per-Gaussian colour of SSD-GS: ``C = (c_d f_d + c_s f_s) · S + c_sss f_sss``, times ``I / d²``.

`Shader` owns the global learnable parts (ASG bases, Θ_SSS, Θ_shad) and turns the raw per-Gaussian
attributes of the visible Gaussians into colour components; the method splats them as feature channels.
Per-Gaussian attributes (raw, activations applied here): ``diffuse`` (K, 3) and ``specular`` (K, 3) and
``sss`` (K, 3) colours through softplus, ``asg_weights`` (K, N) through softplus, ``material`` (K, M) as
is, optionally ``shading_quat`` (K, 4) for the official code's learned shading frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from olatbench.gaussians.projection import quat_to_rotmat
from olatbench.methods.ssdgs.config import SSDGSConfig
from olatbench.methods.ssdgs.shading import (
    inverse_square_irradiance,
    lambert_cosine,
    min_scale_frames,
    orient_frames,
    safe_normalize,
    schlick_fresnel,
)
from olatbench.methods.ssdgs.shadow_mlp import ShadowNetwork
from olatbench.methods.ssdgs.specular import ASGMixture
from olatbench.methods.ssdgs.sss import SSSNetwork


@dataclass
class Components:
    """Per-Gaussian shading of K Gaussians: ``colour`` (K, 3) and its parts, all including ``I / d²``.

    ``diffuse``/``specular``/``sss`` (K, 3) are unshadowed; ``shadow`` (K, 1) is S (1 when the term is
    off) and ``shadow_coarse`` (K, 1) the light-view visibility v̂ (1 when not computed)."""

    colour: torch.Tensor
    diffuse: torch.Tensor
    specular: torch.Tensor
    sss: torch.Tensor
    shadow: torch.Tensor
    shadow_coarse: torch.Tensor


class Shader(nn.Module):
    """The global networks of SSD-GS and the per-Gaussian shading function."""

    def __init__(self, config: SSDGSConfig) -> None:
        super().__init__()
        self.config = config
        self.asg = ASGMixture(config.num_asg, config.asg_form)
        self.sss_net = SSSNetwork(config.material_dim, config.sss_hidden, config.sss_layers, config.sss_freqs,
                                  config.dipole_eta, config.dipole_virtual_factor)
        self.shadow_net = ShadowNetwork(config.material_dim, config.shadow_hidden, config.shadow_layers,
                                        config.shadow_freqs)

    def frames(self, attributes: dict[str, torch.Tensor], quats: torch.Tensor, scales: torch.Tensor,
               wo: torch.Tensor) -> torch.Tensor:
        """(K, 3, 3) shading frames (columns x, y, z = normal)."""
        if self.config.shading_frame == "learned":
            frames = quat_to_rotmat(attributes["shading_quat"])
        else:
            frames = min_scale_frames(quat_to_rotmat(quats), scales)
        return orient_frames(frames, wo) if self.config.orient_normals else frames

    def forward(self, positions: torch.Tensor, quats: torch.Tensor, scales: torch.Tensor,
                attributes: dict[str, torch.Tensor], camera_position: torch.Tensor, light_position: torch.Tensor,
                intensity: torch.Tensor, terms: frozenset[str], coarse_visibility: torch.Tensor | None = None,
                ) -> Components:
        """Shade K Gaussians (``positions`` (K,3), ``quats`` (K,4), ``scales`` (K,3), attributes (K, ·)).

        ``terms`` ⊆ {"specular", "sss", "shadow"} are switched on (diffuse always is); ``coarse_visibility``
        (K,) is required when "shadow" is on.
        """
        wi, incident = inverse_square_irradiance(positions, light_position, intensity)
        wo = safe_normalize(camera_position[None, :] - positions)
        frames = self.frames(attributes, quats, scales, wo)
        normals = frames[:, :, 2]
        ones = positions.new_ones(positions.shape[0], 1)
        zeros3 = positions.new_zeros(positions.shape[0], 3)

        diffuse = F.softplus(attributes["diffuse"]) / math.pi * lambert_cosine(normals, wi, self.config.diffuse_cosine)
        specular = zeros3
        if "specular" in terms:
            half = safe_normalize(wi + wo)
            h_local = torch.einsum("ki,kij->kj", half, frames)
            lobes = self.asg(h_local, F.softplus(attributes["asg_weights"]))
            specular = F.softplus(attributes["specular"]) * schlick_fresnel(wi, half, self.config.fresnel_f0) * lobes
        sss = zeros3
        if "sss" in terms:
            sss = F.softplus(attributes["sss"]) * self.sss_net(positions, wo, wi, normals, attributes["material"])
        shadow, coarse = ones, ones
        if "shadow" in terms:
            if coarse_visibility is None:
                raise ValueError("the shadow term needs the coarse light-view visibility")
            coarse = coarse_visibility[:, None].to(positions.dtype)
            shadow = self.shadow_net(positions, wi, coarse, attributes["material"])

        diffuse, specular, sss = diffuse * incident, specular * incident, sss * incident
        if self.config.shadow_on_sss:
            colour = (diffuse + specular + sss) * shadow
        else:
            colour = (diffuse + specular) * shadow + sss
        return Components(colour, diffuse, specular, sss, shadow, coarse)
