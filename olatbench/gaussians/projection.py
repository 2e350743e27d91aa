"""EWA projection of 3D Gaussians to screen-space 2D Gaussians (as in 3D Gaussian Splatting).

Conventions (shared by the whole Gaussian core):

- ``w2c`` is a (4, 4) world-to-camera matrix in **OpenCV axes** (x right, y down, z forward).
- ``K`` is (3, 3) in pixels with **pixel centres at +0.5**: pixel (x, y) covers [x, x+1) × [y, y+1)
  and the rasterizer evaluates it at (x + 0.5, y + 0.5). Because ``K`` already follows this
  convention, the 2D mean is simply ``K @ (x/z, y/z, 1)`` with no half-pixel shift (the original
  3DGS code instead uses integer pixel centres and an NDC round trip; the two agree once that shift
  is accounted for).
- Quaternions are ``wxyz`` and may be unnormalised (they are normalised here); scales are linear
  (not log).

Gradients reach ``means``, ``quats``, ``scales`` and ``w2c`` (the camera pose); ``K`` is treated as
a constant. Two implementations of the same formulas: plain differentiable torch (the reference; any
device and dtype) and the C++ kernel of :mod:`olatbench.gaussians.backends.cpu` (forward and
hand-written backward in float64 arithmetic whatever the tensors' dtype; ≈ 4× faster
forward+backward on the CPU). ``backend="auto"`` uses the C++ one wherever the C++ rasterizer runs
(CPU float32/float64 tensors, ``K`` without gradient). Its float32 results differ from torch's
float32 ones by rounding, so a radius ``ceil(3·sqrt(λ_max))`` that lands within rounding of an
integer can differ by one pixel.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from olatbench._native import Unavailable

from .backends import resolve_kernel_backend
from .backends.cpu import project_cpu
from .screen import FRUSTUM_CLAMP, RADIUS_SIGMAS, frustum_clamp_bounds


@dataclass
class Projected:
    """Screen-space Gaussians for one camera.

    ``means2d`` (N, 2) px, ``conics`` (N, 3) = (a, b, c) of the inverse 2D covariance
    [[a, b], [b, c]] in px⁻², ``radii`` (N,) int64 px (0 = culled: behind the near plane, beyond
    far, degenerate or off-screen), ``depths`` (N,) camera-space z (same units as the scene),
    ``width``/``height`` of the image in px.
    """

    means2d: torch.Tensor
    conics: torch.Tensor
    radii: torch.Tensor
    depths: torch.Tensor
    width: int
    height: int

    @property
    def visible(self) -> torch.Tensor:
        """(N,) bool: Gaussians that survive culling."""
        return self.radii > 0


def quat_to_rotmat(quats: torch.Tensor) -> torch.Tensor:
    """Rotation matrices (N, 3, 3) from ``wxyz`` quaternions (N, 4) (normalised here)."""
    q = quats / quats.norm(dim=-1, keepdim=True)
    w, x, y, z = q.unbind(-1)
    rows = [
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ]  # fmt: skip
    return torch.stack(rows, dim=-1).reshape((*q.shape[:-1], 3, 3))


def covariances_3d(quats: torch.Tensor, scales: torch.Tensor) -> torch.Tensor:
    """World-space covariances Σ = R S Sᵀ Rᵀ (N, 3, 3) from quaternions (N, 4) and linear scales
    (N, 3)."""
    rs = quat_to_rotmat(quats) * scales[:, None, :]
    return rs @ rs.transpose(-1, -2)


def perspective_jacobian(
    fx: torch.Tensor, fy: torch.Tensor, z: torch.Tensor, u: torch.Tensor, v: torch.Tensor
) -> torch.Tensor:
    """(N, 2, 3) Jacobian of the pinhole projection ``(fx·x/z, fy·y/z)`` at camera-space depth ``z``
    (N,) with ``u = x/z`` and ``v = y/z`` (N,) as given (each caller clamps them by its own frustum
    rule)."""
    zeros = torch.zeros_like(z)
    return torch.stack(
        [
            torch.stack([fx / z, zeros, -fx * u / z], dim=-1),
            torch.stack([zeros, fy / z, -fy * v / z], dim=-1),
        ],
        dim=-2,
    )


def project(
    means: torch.Tensor,
    quats: torch.Tensor,
    scales: torch.Tensor,
    w2c: torch.Tensor,
    K: torch.Tensor,
    width: int,
    height: int,
    near: float = 0.01,
    far: float = 1e10,
    low_pass: float = 0.3,
    backend: str = "auto",
) -> Projected:
    """Project 3D Gaussians (means (N, 3), quats (N, 4) wxyz, scales (N, 3)) with camera
    ``w2c``/``K``.

    The 2D covariance is J W Σ Wᵀ Jᵀ + ``low_pass``·I (the 3DGS 0.3 px anti-aliasing filter), where
    J is the Jacobian of the perspective projection at the camera-space mean with x/z and y/z
    clamped to [-(cx/fx) - 0.3·w/(2fx), (w-cx)/fx + 0.3·w/(2fx)] (and likewise for y) — for a
    centred principal point this is exactly 3DGS's ±1.3·tan(fov/2).
    ``radius = ceil(3·sqrt(λ_max))``. A Gaussian gets radius 0 when its depth is outside
    [near, far], its 2D covariance is not positive definite, or its box mean ± radius misses the
    image. ``backend``: "torch", "cpu" (the C++ kernel) or "auto" (see the module docstring).
    """

    def cpu_inputs() -> Unavailable | None:
        if K.requires_grad:
            return Unavailable("it gives K no gradient, and K requires grad")
        if any(t.device.type != "cpu" for t in (means, quats, scales, w2c, K)):
            return Unavailable("it needs every tensor on the CPU")
        return None

    if (
        resolve_kernel_backend(backend, means.device, means.dtype, "projection", cpu_inputs)
        == "cpu"
    ):
        means2d, conics, radii, depths = project_cpu(
            means, quats, scales, w2c, K, width, height, near, far, low_pass
        )
        return Projected(
            means2d=means2d,
            conics=conics,
            radii=radii,
            depths=depths,
            width=int(width),
            height=int(height),
        )
    dtype = means.dtype
    w2c = w2c.to(dtype)
    K = K.to(device=means.device, dtype=dtype)
    rot = w2c[:3, :3]
    cam = means @ rot.T + w2c[:3, 3]
    x, y, z = cam.unbind(-1)
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]

    # Safe depth for the divisions: culled Gaussians must not produce inf/nan that would poison
    # gradients.
    in_range = (z > near) & (z < far)
    z_safe = torch.where(in_range, z, torch.ones_like(z))
    u = x / z_safe
    v = y / z_safe
    means2d = torch.stack([fx * u + cx, fy * v + cy], dim=-1)

    u_lo, u_hi, v_lo, v_hi = frustum_clamp_bounds(K, width, height).to(dtype).unbind()
    u_c = u.clamp(u_lo, u_hi)
    v_c = v.clamp(v_lo, v_hi)
    jac = perspective_jacobian(fx, fy, z_safe, u_c, v_c)
    cov_cam = rot @ covariances_3d(quats, scales) @ rot.T
    cov2d = jac @ cov_cam @ jac.transpose(-1, -2)
    a = cov2d[:, 0, 0] + low_pass
    b = cov2d[:, 0, 1]
    c = cov2d[:, 1, 1] + low_pass
    det = a * c - b * b
    ok = in_range & (det > 0)
    det_safe = torch.where(ok, det, torch.ones_like(det))
    conics = torch.stack([c / det_safe, -b / det_safe, a / det_safe], dim=-1)

    with torch.no_grad():
        mid = 0.5 * (a + c)
        lam_max = mid + torch.sqrt(torch.clamp(mid * mid - det, min=0.0))
        radius = torch.ceil(RADIUS_SIGMAS * torch.sqrt(lam_max.clamp(min=0.0)))
        mx, my = means2d.unbind(-1)
        on_screen = (
            (mx + radius > 0) & (mx - radius < width) & (my + radius > 0) & (my - radius < height)
        )
        keep = ok & on_screen & torch.isfinite(radius)
        radii = torch.where(keep, radius, torch.zeros_like(radius)).to(torch.int64)
    return Projected(
        means2d=means2d, conics=conics, radii=radii, depths=z, width=int(width), height=int(height)
    )


__all__ = [
    "FRUSTUM_CLAMP",
    "RADIUS_SIGMAS",
    "Projected",
    "covariances_3d",
    "frustum_clamp_bounds",
    "perspective_jacobian",
    "project",
    "quat_to_rotmat",
]
