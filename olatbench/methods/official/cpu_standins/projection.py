"""gsplat 1.1.1's ``fully_fused_projection`` (``packed=False``, no ``calc_compensations``) in
differentiable torch.

The stand-in of ``gsplat.rasterization`` projects with this rather than with olatbench's own
projection (`olatbench.gaussians.projection`, which follows 3DGS and stays as it is for the native
methods), because the two differ where training depends on it. Per camera and Gaussian, as
``gsplat/cuda/csrc/fully_fused_projection_fwd.cu`` and ``utils.cuh`` at tag v1.1.1 compute it:

- culled (radius 0) when the camera-space depth z is ``< near_plane`` or ``> far_plane``
  (``fwd.cu:59``): a Gaussian at exactly ``z == near_plane`` is kept (olatbench's projection culls
  it);
- the perspective Jacobian is evaluated with x/z and y/z clamped to ``±1.3 · W / (2 fx)`` and
  ``±1.3 · H / (2 fy)`` (``utils.cuh:154-157`` the limits, ``:161-162`` the clamp): symmetric about
  the optical axis whatever the principal point (olatbench clamps at the image edges plus 0.3
  half-widths, which agrees only when cx = W/2);
- ``eps2d`` is added to the 2D covariance's diagonal (``add_blur``, ``utils.cuh:303-310``); culled
  when the determinant is ``<= 0`` (``fwd.cu:90-93``);
- ``radius = ceil(3 · sqrt(b + sqrt(max(0.01, b² − det))))`` with ``b`` half the trace
  (``fwd.cu:99-102``; olatbench floors ``b² − det`` at 0, so a nearly isotropic footprint gets a
  radius up to 1 px smaller);
- culled when ``radius <= radius_clip`` (``fwd.cu:106``) or when the box ``mean ± radius`` lies
  outside the image (``fwd.cu:112-113``, ``<= 0`` / ``>= width``).

Culled Gaussians get zero means2d, conics and depths, as the kernel leaves its zero-initialised
outputs unwritten. Gradients are autograd's through these formulas, which is what gsplat's
hand-written backward computes (``utils.cuh:174-235``, ``persp_proj_vjp``: the clamped coordinate
passes its gradient to z, not to x or y).
"""

from __future__ import annotations

import torch

from olatbench.gaussians.projection import Projected, covariances_3d, perspective_jacobian
from olatbench.gaussians.tiles import TILE_SIZE, TileBins, bins_of_tile_ranges

FRUSTUM_CLAMP = 1.3  # utils.cuh:156-157
RADIUS_FLOOR = 0.01  # fully_fused_projection_fwd.cu:101: the floor under b² − det
RADIUS_SIGMAS = 3.0  # fully_fused_projection_fwd.cu:102


def project_gsplat(
    means: torch.Tensor,
    quats: torch.Tensor,
    scales: torch.Tensor,
    viewmat: torch.Tensor,
    K: torch.Tensor,
    width: int,
    height: int,
    near_plane: float,
    far_plane: float,
    eps2d: float,
    radius_clip: float = 0.0,
) -> Projected:
    """One camera's projection as gsplat 1.1.1 computes it (module docstring): ``means`` (N, 3),
    ``quats`` (N, 4) wxyz (normalised here), ``scales`` (N, 3) linear, ``viewmat`` (4, 4)
    world-to-camera in OpenCV axes, ``K`` (3, 3) px with pixel centres at +0.5. Returns means2d
    (N, 2) px, conics (N, 3), radii (N,) int64, depths (N,)."""
    dtype = means.dtype
    viewmat = viewmat.to(dtype)
    K = K.to(device=means.device, dtype=dtype).detach()
    rot = viewmat[:3, :3]
    cam = means @ rot.T + viewmat[:3, 3]
    x, y, z = cam.unbind(-1)
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    in_range = (z >= near_plane) & (z <= far_plane) & (z != 0)
    z_safe = torch.where(in_range, z, torch.ones_like(z))
    lim_x = FRUSTUM_CLAMP * 0.5 * width / fx
    lim_y = FRUSTUM_CLAMP * 0.5 * height / fy
    u_c = torch.minimum(lim_x, torch.maximum(-lim_x, x / z_safe))
    v_c = torch.minimum(lim_y, torch.maximum(-lim_y, y / z_safe))
    jac = perspective_jacobian(fx, fy, z_safe, u_c, v_c)
    cov2d = jac @ (rot @ covariances_3d(quats, scales) @ rot.T) @ jac.transpose(-1, -2)
    a = cov2d[:, 0, 0] + eps2d
    b = cov2d[:, 0, 1]
    c = cov2d[:, 1, 1] + eps2d
    det = a * c - b * b
    means2d = torch.stack([fx * x / z_safe + cx, fy * y / z_safe + cy], dim=-1)
    with torch.no_grad():
        half_trace = 0.5 * (a + c)
        v1 = half_trace + torch.sqrt(torch.clamp(half_trace * half_trace - det, min=RADIUS_FLOOR))
        radius = torch.ceil(RADIUS_SIGMAS * torch.sqrt(v1))
        mx, my = means2d.unbind(-1)
        on_screen = (
            (mx + radius > 0) & (mx - radius < width) & (my + radius > 0) & (my - radius < height)
        )
        keep = in_range & (det > 0) & (radius > radius_clip) & on_screen & torch.isfinite(radius)
        radii = torch.where(keep, radius, torch.zeros_like(radius)).to(torch.int64)
    det_safe = torch.where(keep, det, torch.ones_like(det))
    conics = torch.stack([c / det_safe, -b / det_safe, a / det_safe], dim=-1)
    kept = keep[:, None]
    return Projected(
        means2d=torch.where(kept, means2d, torch.zeros_like(means2d)),
        conics=torch.where(kept, conics, torch.zeros_like(conics)),
        radii=radii,
        depths=torch.where(keep, z, torch.zeros_like(z)),
        width=int(width),
        height=int(height),
    )


def gsplat_bins(projected: Projected) -> TileBins:
    """gsplat 1.1.1's tile lists (``isect_tiles.cu:55-64``): a Gaussian goes to the 16-px tiles
    ``[floor((m − r)/16), ceil((m + r)/16))`` per axis (clamped to the grid), each list front to
    back by depth (ties in Gaussian order, as its stable radix sort of ``tile << 32 | depth bits``).
    This can include a tile beyond the pixel box ``m ± r`` that olatbench's binning
    (`olatbench.gaussians.tiles.bin_gaussians`) stops at; the rasterizer composites every Gaussian
    of a tile's list wherever its alpha reaches 1/255."""
    width, height = projected.width, projected.height
    tiles_x, tiles_y = (width + TILE_SIZE - 1) // TILE_SIZE, (height + TILE_SIZE - 1) // TILE_SIZE
    tile_means = projected.means2d.detach() / TILE_SIZE
    tile_radii = projected.radii.to(tile_means.dtype) / TILE_SIZE
    lo = torch.floor(tile_means - tile_radii[:, None]).to(torch.int64)
    hi = torch.ceil(tile_means + tile_radii[:, None]).to(torch.int64)
    tx0, ty0 = lo[:, 0].clamp(0, tiles_x), lo[:, 1].clamp(0, tiles_y)
    tx1, ty1 = hi[:, 0].clamp(0, tiles_x), hi[:, 1].clamp(0, tiles_y)
    inside = (projected.radii > 0) & (tx1 > tx0) & (ty1 > ty0)
    return bins_of_tile_ranges(
        (tx0, tx1, ty0, ty1), inside, projected.depths, width, height, TILE_SIZE
    )


__all__ = ["FRUSTUM_CLAMP", "RADIUS_FLOOR", "RADIUS_SIGMAS", "gsplat_bins", "project_gsplat"]
