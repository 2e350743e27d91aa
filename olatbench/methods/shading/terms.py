"""Closed-form shading terms of SSD-GS, evaluated per Gaussian (no image-space work here).

Conventions: directions are unit vectors pointing *away* from the Gaussian centre (``wi`` towards
the light, ``wo`` towards the camera); per-Gaussian tensors have a leading dimension K (the visible
Gaussians). A shading frame is a (K, 3, 3) matrix whose *columns* are the local x, y and z (normal)
axes in world coordinates, so ``v_local = v @ frame`` (row vectors).
"""

from __future__ import annotations

import math
from typing import Literal

import torch
import torch.nn.functional as F

DiffuseCosine = Literal["clamped", "smooth"]
SMOOTH_COSINE_ALPHA = 0.01  # ELU slope of the official smooth cosine


def safe_normalize(v: torch.Tensor, eps: float = 1e-8) -> torch.Tensor:
    """Unit vectors along the last dimension (zero vectors stay zero)."""
    return F.normalize(v, dim=-1, eps=eps)


def min_scale_frames(rotations: torch.Tensor, scales: torch.Tensor) -> torch.Tensor:
    """Shading frames whose z axis is each Gaussian's axis of smallest scale.

    ``rotations`` (K, 3, 3) (columns = the Gaussian's axes), ``scales`` (K, 3). The axes are
    permuted cyclically (``z = axis k``, ``x = axis k+1``, ``y = axis k+2``) so the frame stays
    right-handed.
    """
    k = torch.argmin(scales, dim=-1)  # (K,)
    order = torch.stack([(k + 1) % 3, (k + 2) % 3, k], dim=-1)  # (K, 3)
    return torch.gather(rotations, 2, order[:, None, :].expand(-1, 3, -1))


def orient_frames(frames: torch.Tensor, wo: torch.Tensor) -> torch.Tensor:
    """Flip frames whose normal faces away from ``wo`` (K, 3); x flips too, so handedness is
    kept."""
    sign = torch.where((frames[:, :, 2] * wo).sum(-1) < 0, -1.0, 1.0).to(frames.dtype)  # (K,)
    flip = torch.stack([sign, torch.ones_like(sign), sign], dim=-1)  # x, y, z column signs
    return frames * flip[:, None, :]


def lambert_cosine(
    normals: torch.Tensor, wi: torch.Tensor, mode: DiffuseCosine = "smooth"
) -> torch.Tensor:
    """Diffuse cosine factor f_d (K, 1).

    ``"clamped"``: the paper's ``max(0, n·ωi)``. ``"smooth"``: the official code's smooth clamp
    ``(ELU_a(n·ωi) + a(1 - 1/e)) / (1 + a(1 - 1/e))`` with ``a = 0.01``: it equals 0 at n·ωi = -1, 1
    at n·ωi = 1, is ≈ n·ωi for n·ωi > 0 and keeps a small non-zero gradient for back-facing normals.
    """
    cos = (normals * wi).sum(-1, keepdim=True)
    if mode == "clamped":
        return cos.clamp_min(0.0)
    if mode == "smooth":
        offset = SMOOTH_COSINE_ALPHA * (1.0 - 1.0 / math.e)
        return (F.elu(cos, alpha=SMOOTH_COSINE_ALPHA) + offset) / (1.0 + offset)
    raise ValueError(f"diffuse_cosine must be 'clamped' or 'smooth', not {mode!r}")


def schlick_fresnel(wi: torch.Tensor, half: torch.Tensor, f0: float = 0.04) -> torch.Tensor:
    """Schlick's Fresnel ``F0 + (1 - F0)(1 - ωi·h)^5`` (K, 1); ``ωi·h`` is clamped to [0, 1]."""
    cos = (wi * half).sum(-1, keepdim=True).clamp(0.0, 1.0)
    return f0 + (1.0 - f0) * (1.0 - cos) ** 5


def inverse_square_irradiance(
    points: torch.Tensor, light_position: torch.Tensor, intensity: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Direction to the light and incident light ``I / d²`` at world points.

    ``points`` (K, 3), ``light_position`` (3,), ``intensity`` (3,) RGB -> ``(wi (K, 3), irradiance
    (K, 3))``.
    """
    to_light = light_position[None, :] - points
    dist2 = (to_light * to_light).sum(-1, keepdim=True).clamp_min(1e-12)
    return to_light * torch.rsqrt(dist2), intensity[None, :] / dist2
