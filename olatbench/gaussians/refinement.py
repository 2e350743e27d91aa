"""Per-image camera-pose and per-light position refinement (SSD-GS "w/ Opt").

Pose: each image i owns a zero-initialised tangent vector ξ_i = (t, ω) ∈ R⁶ (translation first,
rotation second, the nerfstudio ``exp_map_SO3xR3`` layout the official code uses). It becomes the
camera-space rigid delta Δ = [[exp(ω^), t], [0, 1]] (rotation by the SO(3) exponential map,
translation *not* coupled to it, i.e. SO3×R3 rather than SE3), applied on the camera side:
``w2c' = Δ @ w2c``. At ξ = 0, Δ = I exactly, and the map is differentiable everywhere (a Taylor
expansion is used near ω = 0).

Light: each light j owns a zero-initialised world-space offset δ_j ∈ R³: ``position' = position +
δ_j``.
"""

from __future__ import annotations

import torch
from torch import nn

# Below this squared angle the Rodrigues coefficients use their Taylor expansions.
_SMALL_ANGLE_SQ = 1e-8


def hat(omega: torch.Tensor) -> torch.Tensor:
    """Skew-symmetric matrices (..., 3, 3) with ``hat(ω) @ v = ω × v`` for ω (..., 3)."""
    x, y, z = omega.unbind(-1)
    zero = torch.zeros_like(x)
    rows = [zero, -z, y, z, zero, -x, -y, x, zero]
    return torch.stack(rows, dim=-1).reshape((*omega.shape[:-1], 3, 3))


def so3_exp(omega: torch.Tensor) -> torch.Tensor:
    """Rotation matrices (..., 3, 3) = exp(hat(ω)) by Rodrigues' formula, differentiable at ω =
    0."""
    theta_sq = (omega * omega).sum(-1)
    small = theta_sq < _SMALL_ANGLE_SQ
    theta = torch.sqrt(torch.where(small, torch.ones_like(theta_sq), theta_sq))
    a = torch.where(small, 1.0 - theta_sq / 6.0, torch.sin(theta) / theta)  # sin θ / θ
    # (1 - cos θ) / θ²
    b = torch.where(small, 0.5 - theta_sq / 24.0, (1.0 - torch.cos(theta)) / (theta * theta))
    k = hat(omega)
    eye = torch.eye(3, dtype=omega.dtype, device=omega.device).expand(k.shape)
    return eye + a[..., None, None] * k + b[..., None, None] * (k @ k)


def so3xr3_exp(xi: torch.Tensor) -> torch.Tensor:
    """Rigid transforms (..., 4, 4) from tangents ξ = (t, ω) (..., 6): [[exp(ω^), t], [0, 1]]."""
    rotation = so3_exp(xi[..., 3:])
    top = torch.cat([rotation, xi[..., :3, None]], dim=-1)
    # [0, 0, 0, 1] made on the device (assigning a Python 1.0 into a CUDA tensor copies it from the
    # host)
    bottom = torch.eye(4, dtype=xi.dtype, device=xi.device)[3:].expand(*xi.shape[:-1], 1, 4)
    return torch.cat([top, bottom], dim=-2)


class PoseRefinement(nn.Module):
    """Zero-initialised per-image SO3×R3 deltas applied in camera space:
    ``w2c' = exp(ξ_i) @ w2c``."""

    def __init__(
        self,
        num_images: int,
        device: torch.device | str | None = None,
        dtype: torch.dtype = torch.float32,
    ):
        super().__init__()
        self.tangents = nn.Parameter(torch.zeros(num_images, 6, device=device, dtype=dtype))

    def delta(self, index: int | torch.Tensor) -> torch.Tensor:
        """The camera-space delta(s) (4, 4) or (B, 4, 4) for image ``index``
        (int or int64 tensor)."""
        return so3xr3_exp(self.tangents[index])

    def apply(self, index: int | torch.Tensor, w2c: torch.Tensor) -> torch.Tensor:
        """Refined world-to-camera matrix/matrices for image ``index``; ``w2c`` (4, 4) or
        (B, 4, 4)."""
        return self.delta(index).to(w2c.dtype) @ w2c


class LightRefinement(nn.Module):
    """Zero-initialised per-light world-space offsets: ``position' = position + δ_j``."""

    def __init__(
        self,
        num_lights: int,
        device: torch.device | str | None = None,
        dtype: torch.dtype = torch.float32,
    ):
        super().__init__()
        self.offsets = nn.Parameter(torch.zeros(num_lights, 3, device=device, dtype=dtype))

    def apply(self, index: int | torch.Tensor, position: torch.Tensor) -> torch.Tensor:
        """Refined position(s) (3,) or (B, 3) of light ``index``."""
        return position + self.offsets[index].to(position.dtype)


__all__ = ["LightRefinement", "PoseRefinement", "hat", "so3_exp", "so3xr3_exp"]
