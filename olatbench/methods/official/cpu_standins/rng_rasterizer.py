"""``diff_gaussian_rasterization`` as RNG (sssssy/RNG_release @ 4e8748e) forks it, on the CPU with
olatbench's projection and rasterizer.

RNG's fork of the Inria rasterizer (graphdeco-inria/diff-gaussian-rasterization @ 59f5f77) adds a
low-pass radius, ``depth`` and ``alpha`` outputs (no gradient flows through them: returned detached
here) and 16 colour channels; Inria's culling, radius, tile and compositing rules are kept. SH
colours, ``cov3D_precomp``, ``prefiltered`` and an off-centre ``projmatrix`` raise
`NotImplementedError`. docs/official.md (the CPU stand-ins' table) cites the fork's lines for each
rule and the two small differences.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import torch
from torch import nn

from olatbench.gaussians.projection import Projected, project
from olatbench.gaussians.rasterize import rasterize
from olatbench.gaussians.tiles import TileBins, float_order_key

NUM_CHANNELS = 16  # cuda_rasterizer/config.h:15
NEAR = 0.2  # auxiliary.h:154: p_view.z <= 0.2 is culled
BLOCK = 16  # config.h:16-17, the tile getRect counts in


class GaussianRasterizationSettings(NamedTuple):
    """RNG's settings (``diff_gaussian_rasterization/__init__.py:160-174``); matrices are
    column-major (``p @ M``)."""

    image_height: int
    image_width: int
    tanfovx: float
    tanfovy: float
    bg: torch.Tensor
    scale_modifier: float
    viewmatrix: torch.Tensor
    projmatrix: torch.Tensor
    sh_degree: int
    campos: torch.Tensor
    prefiltered: bool
    debug: bool
    low_pass_filter_radius: float


def _refuse(what: str) -> None:
    raise NotImplementedError(
        f"diff_gaussian_rasterization stand-in (olatbench CPU, RNG's fork): {what} is not "
        "implemented; RNG's commands pass colors_precomp (--color_mlp), scales and rotations"
    )


def inria_radii(
    means2d: torch.Tensor, conics: torch.Tensor, keep: torch.Tensor, width: int, height: int
) -> torch.Tensor:
    """(N,) int64 radii by Inria's rule (``forward.cu:230-238``): from the 2D covariance (the
    inverse of ``conics`` (N, 3)) ``ceil(3 sqrt(mid + sqrt(max(0.1, mid² - det))))``, 0 where
    ``keep`` is False or the Gaussian's tile rectangle (``getRect``, integer-truncated, 16-pixel
    tiles) is empty. ``means2d`` (N, 2) in olatbench's pixel convention (centres at +0.5; Inria's
    ``point_image`` is 0.5 less)."""
    with torch.no_grad():
        a_inv, b_inv, c_inv = conics.detach().double().unbind(-1)
        det_inv = a_inv * c_inv - b_inv * b_inv
        safe = torch.where(det_inv > 0, det_inv, torch.ones_like(det_inv))
        a, c, b = c_inv / safe, a_inv / safe, -b_inv / safe
        det = a * c - b * b
        mid = 0.5 * (a + c)
        root = torch.sqrt(torch.clamp(mid * mid - det, min=0.1))
        radius = torch.ceil(
            3.0 * torch.sqrt(torch.clamp(torch.maximum(mid + root, mid - root), min=0.0))
        )
        point = means2d.detach().double() - 0.5
        grid = torch.tensor(
            [math.ceil(width / BLOCK), math.ceil(height / BLOCK)], dtype=torch.float64
        )
        low = torch.minimum(
            grid, torch.clamp(torch.trunc((point - radius[:, None]) / BLOCK), min=0.0)
        )
        high = torch.minimum(
            grid, torch.clamp(torch.trunc((point + radius[:, None] + BLOCK - 1) / BLOCK), min=0.0)
        )
        area = (high - low).prod(dim=-1)
        visible = keep & (det_inv > 0) & (area > 0) & torch.isfinite(radius)
        return torch.where(visible, radius, torch.zeros_like(radius)).to(torch.int64)


def inria_bins(
    means2d: torch.Tensor, radii: torch.Tensor, depths: torch.Tensor, width: int, height: int
) -> TileBins:
    """Tile bins for olatbench's compositor holding each Gaussian (``radii`` > 0) in the tiles of
    Inria's ``getRect`` (``auxiliary.h:46-56``: ``trunc((p - r) / 16)`` up to ``trunc((p + r + 15) /
    16)``, clamped to the grid, ``p`` in integer pixel centres), which can be one tile wider than
    olatbench's own pixel box (`olatbench.gaussians.tiles`); each tile's list sorted nearest first
    by ``depths`` (ties by index)."""
    tiles_x, tiles_y = math.ceil(width / BLOCK), math.ceil(height / BLOCK)
    point = means2d.detach().double() - 0.5
    r = radii.double()[:, None]
    grid = torch.tensor([tiles_x, tiles_y], dtype=torch.float64)
    low = torch.minimum(grid, torch.clamp(torch.trunc((point - r) / BLOCK), min=0.0)).to(
        torch.int64
    )
    high = torch.minimum(
        grid, torch.clamp(torch.trunc((point + r + BLOCK - 1) / BLOCK), min=0.0)
    ).to(torch.int64)
    span = high - low
    counts = torch.where(radii > 0, span[:, 0] * span[:, 1], torch.zeros_like(radii))
    gauss = torch.repeat_interleave(torch.arange(means2d.shape[0]), counts)
    local = torch.arange(int(counts.sum())) - (torch.cumsum(counts, 0) - counts)[gauss]
    tile_y = low[gauss, 1] + torch.div(local, span[gauss, 0], rounding_mode="floor")
    tile_x = low[gauss, 0] + local - (tile_y - low[gauss, 1]) * span[gauss, 0]
    tile_ids = tile_y * tiles_x + tile_x
    order = torch.sort((tile_ids << 32) | float_order_key(depths)[gauss], stable=True).indices
    offsets = torch.zeros(tiles_x * tiles_y + 1, dtype=torch.int64)
    offsets[1:] = torch.cumsum(torch.bincount(tile_ids, minlength=tiles_x * tiles_y), 0)
    return TileBins(
        offsets=offsets,
        gaussian_ids=gauss[order],
        tile_size=BLOCK,
        tiles_x=tiles_x,
        tiles_y=tiles_y,
        width=int(width),
        height=int(height),
    )


def _check_projection(settings: GaussianRasterizationSettings) -> None:
    """Refuse a ``projmatrix`` that is not ``viewmatrix`` × the symmetric perspective of
    ``tanfovx``/``tanfovy`` (x and y rows); the 2D mean would then differ from the pinhole K used
    here."""
    view, proj = settings.viewmatrix.detach().double(), settings.projmatrix.detach().double()
    perspective = torch.linalg.solve(view, proj)  # column-major: proj = view @ P^T
    expected_x = torch.tensor([1.0 / settings.tanfovx, 0.0, 0.0], dtype=torch.float64)
    expected_y = torch.tensor([0.0, 1.0 / settings.tanfovy, 0.0], dtype=torch.float64)
    if not (
        torch.allclose(perspective[:3, 0], expected_x, atol=1e-4, rtol=1e-4)
        and torch.allclose(perspective[:3, 1], expected_y, atol=1e-4, rtol=1e-4)
        and torch.allclose(
            perspective[:3, 3], torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64), atol=1e-6
        )
    ):
        raise NotImplementedError(
            "diff_gaussian_rasterization stand-in (olatbench CPU): projmatrix is not the "
            "symmetric perspective of tanfovx/tanfovy (RNG's getProjectionMatrix); an "
            "off-centre projection is not implemented"
        )


def rasterize_gaussians(
    means3D: torch.Tensor,
    means2D: torch.Tensor,
    colors_precomp: torch.Tensor,
    opacities: torch.Tensor,
    scales: torch.Tensor,
    rotations: torch.Tensor,
    settings: GaussianRasterizationSettings,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """(color [16, H, W], radii [N] int32, depth [1, H, W], alpha [1, H, W]) (module docstring).
    ``means3D`` [N, 3], ``means2D`` [N, 3] (its values unused, its gradient written),
    ``colors_precomp`` [N, 16], ``opacities`` [N, 1], ``scales`` [N, 3] (× ``scale_modifier``),
    ``rotations`` [N, 4] wxyz."""
    if settings.prefiltered:
        _refuse("prefiltered=True")
    n = means3D.shape[0]
    if colors_precomp.shape != (n, NUM_CHANNELS):
        raise ValueError(
            f"diff_gaussian_rasterization stand-in: colors_precomp must be [N={n}, {NUM_CHANNELS}] "
            f"(RNG's NUM_CHANNELS, cuda_rasterizer/config.h:15), got {tuple(colors_precomp.shape)}"
        )
    _check_projection(settings)
    width, height = int(settings.image_width), int(settings.image_height)
    w2c = settings.viewmatrix.T.to(means3D.dtype)
    K = torch.tensor(
        [
            [width / (2.0 * settings.tanfovx), 0.0, width / 2.0],
            [0.0, height / (2.0 * settings.tanfovy), height / 2.0],
            [0.0, 0.0, 1.0],
        ],
        dtype=means3D.dtype,
    )
    projected = project(
        means3D,
        rotations,
        scales * settings.scale_modifier,
        w2c,
        K,
        width,
        height,
        near=NEAR,
        low_pass=float(settings.low_pass_filter_radius),
    )
    in_front = projected.depths.detach() > NEAR
    radii = inria_radii(projected.means2d, projected.conics, in_front, width, height)
    # backward.cu:460-461
    to_ndc = torch.tensor([0.5 * width, 0.5 * height], dtype=projected.means2d.dtype)
    means2d = (
        projected.means2d
        + (means2D[:, :2] - means2D[:, :2].detach()).to(projected.means2d.dtype) * to_ndc
    )
    camera = Projected(
        means2d=means2d,
        conics=projected.conics,
        radii=radii,
        depths=projected.depths,
        width=width,
        height=height,
    )
    background = torch.zeros(NUM_CHANNELS + 1, dtype=colors_precomp.dtype)
    background[:3] = settings.bg.detach().reshape(-1)[:3].to(colors_precomp.dtype)
    features = torch.cat(
        [colors_precomp, projected.depths.detach()[:, None].to(colors_precomp.dtype)], dim=1
    )
    bins = inria_bins(means2d, radii, projected.depths, width, height)
    out = rasterize(camera, opacities.reshape(-1), features, background, bins=bins)
    image = out.image.permute(2, 0, 1)  # [17, H, W]
    alpha = out.alpha.detach()[None]
    return (
        image[:NUM_CHANNELS].contiguous(),
        radii.to(torch.int32),
        image[NUM_CHANNELS:].detach(),
        alpha,
    )


class GaussianRasterizer(nn.Module):
    """RNG's ``GaussianRasterizer`` (``diff_gaussian_rasterization/__init__.py:176-223``)."""

    def __init__(self, raster_settings: GaussianRasterizationSettings) -> None:
        super().__init__()
        self.raster_settings = raster_settings

    def markVisible(self, positions: torch.Tensor) -> torch.Tensor:
        """(N,) bool: in front of the near plane (Inria's ``in_frustum``, auxiliary.h:154)."""
        with torch.no_grad():
            view = self.raster_settings.viewmatrix.to(positions.dtype)
            return (positions @ view[:3, :3] + view[3, :3])[:, 2] > NEAR

    def forward(
        self,
        means3D,
        means2D,
        opacities,
        shs=None,
        colors_precomp=None,
        scales=None,
        rotations=None,
        cov3D_precomp=None,
    ):
        if (shs is None) == (colors_precomp is None):
            raise Exception("Please provide excatly one of either SHs or precomputed colors!")
        if ((scales is None or rotations is None) and cov3D_precomp is None) or (
            (scales is not None or rotations is not None) and cov3D_precomp is not None
        ):
            raise Exception(
                "Please provide exactly one of either scale/rotation pair or precomputed 3D "
                "covariance!"
            )
        if shs is not None:
            _refuse("shs (SH colours)")
        if cov3D_precomp is not None:
            _refuse("cov3D_precomp")
        return rasterize_gaussians(
            means3D, means2D, colors_precomp, opacities, scales, rotations, self.raster_settings
        )


__all__ = [
    "NUM_CHANNELS",
    "GaussianRasterizationSettings",
    "GaussianRasterizer",
    "inria_radii",
    "rasterize_gaussians",
]
