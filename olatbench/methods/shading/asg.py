"""Specular lobes: a mixture of N global anisotropic spherical Gaussians (ASG) in each Gaussian's
frame.

``D(h) = Σ_j α_j G_j(h)`` where ``h`` is the half vector expressed in the Gaussian's shading frame
and ``α`` (K, N) are per-Gaussian non-negative weights. Two lobe shapes:

* ``"xu"`` (default, the paper's appendix): Xu et al. 2013, ``G_j(h) = max(h·z_j, 0) · exp(-λ_j
  (h·x_j)² - μ_j (h·y_j)²)`` with the smooth term ``max(h·z_j, 0)`` of the original ASG definition,
  unit amplitude.
* ``"official"``: the official SSD-GS code's angular anisotropic Gaussian,
  ``G_j(h) = exp(-½ (θ · a(h) / σ_j)²) / (√2 π^{2/3} σ_j)`` with ``θ = arccos(h·z_j)`` and
  ``a(h) = ‖((s·x_j)/λ_j, (s·y_j)/μ_j)‖``, ``s`` = h projected on the tangent plane and normalised.

Both are initialised to the same lobe widths as the official code (8 bases from sharp to wide,
anisotropy 2.5 : 1, all centred on the normal), so the two forms start from comparable highlights.
"""

from __future__ import annotations

import math
from typing import Literal

import torch
import torch.nn.functional as F
from torch import nn

from olatbench.gaussians.projection import quat_to_rotmat

ASGForm = Literal["xu", "official"]
_OFFICIAL_NORMALISER = math.sqrt(2.0) * math.pow(math.pi, 2.0 / 3.0)
_INIT_ANISOTROPY = 2.5  # official init: λ = 2.5, μ = 1.0 (sigmoid(-1.0986)·10, sigmoid(-2.1972)·10)


def _official_sigma_ratio(num_bases: int) -> torch.Tensor:
    return F.softplus(torch.linspace(-2.0, 0.0, steps=num_bases, device="cpu"))


class ASGMixture(nn.Module):
    """N global ASG bases with learnable frames and widths; ``forward(h_local, weights) -> (K,
    1)``."""

    def __init__(self, num_bases: int = 8, form: ASGForm = "xu") -> None:
        super().__init__()
        if form not in ("xu", "official"):
            raise ValueError(f"asg_form must be 'xu' or 'official', not {form!r}")
        self.form = form
        self.num_bases = num_bases
        rotation = torch.zeros(num_bases, 4, device="cpu")
        rotation[:, 0] = 1.0
        self.rotation = nn.Parameter(rotation)  # (N, 4) wxyz, lobe frames in the Gaussian's frame
        # Official angular std of basis j along y: σ_j = sigmoid(0) · softplus(linspace(-2, 0)).
        angular_std = 0.5 * _official_sigma_ratio(num_bases)
        if form == "xu":
            # Match the official widths for small angles: exp(-λ θ²) has std 1/sqrt(2λ).
            lam = 1.0 / (2.0 * (_INIT_ANISOTROPY * angular_std) ** 2)
            mu = 1.0 / (2.0 * angular_std**2)
            self.log_sharpness = nn.Parameter(torch.stack([lam.log(), mu.log()], dim=-1))  # (N, 2)
        else:
            self.register_buffer("sigma_ratio", _official_sigma_ratio(num_bases), persistent=False)
            self.raw_sigma = nn.Parameter(torch.zeros(num_bases, device="cpu"))
            scales = torch.full((num_bases, 2), -2.1972, device="cpu")
            scales[:, 0] *= 0.5
            self.raw_scales = nn.Parameter(scales)  # λ, μ = 10 · sigmoid(raw)

    def lobe_parameters(self, include_sigma: bool = True) -> list[nn.Parameter]:
        """The lobe shape parameters that Schedule I freezes early in the specular phase: frames and
        widths, and in the ``"official"`` form σ unless ``include_sigma`` is False (the official
        code freezes only its ``asg_scales`` and ``asg_rotation``)."""
        if self.form == "official" and not include_sigma:
            return [self.rotation, self.raw_scales]
        return list(self.parameters())

    def frames(self) -> torch.Tensor:
        """(N, 3, 3) lobe frames (columns x_j, y_j, z_j) in the Gaussian's shading frame."""
        return quat_to_rotmat(self.rotation)

    def forward(self, h_local: torch.Tensor, weights: torch.Tensor) -> torch.Tensor:
        """``h_local`` (K, 3) unit half vectors in shading frames, ``weights`` (K, N) >= 0 -> D
        (K, 1)."""
        axes = self.frames()
        hx = h_local @ axes[:, :, 0].T  # (K, N)
        hy = h_local @ axes[:, :, 1].T
        hz = h_local @ axes[:, :, 2].T
        if self.form == "xu":
            lam, mu = self.log_sharpness.exp().unbind(-1)
            lobes = hz.clamp_min(0.0) * torch.exp(-lam * hx**2 - mu * hy**2)
        else:
            lam, mu = (10.0 * torch.sigmoid(self.raw_scales)).clamp_min(1e-4).unbind(-1)
            sigma = (torch.sigmoid(self.raw_sigma) * self.sigma_ratio).clamp_min(1e-4)
            # s = normalised projection on the lobe's xy plane
            tangent = torch.stack([hx, hy], dim=-1)
            tangent = F.normalize(tangent, dim=-1, eps=1e-8)
            anisotropy = torch.sqrt((tangent[..., 0] / lam) ** 2 + (tangent[..., 1] / mu) ** 2)
            theta = torch.arccos(hz.clamp(-1 + 1e-6, 1 - 1e-6))
            lobes = torch.exp(-0.5 * (theta * anisotropy / sigma) ** 2) / (
                _OFFICIAL_NORMALISER * sigma
            )
        return (weights * lobes).sum(-1, keepdim=True)
