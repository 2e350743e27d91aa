"""``diff_gaussian_rasterization_light`` (the authors' light-view shadow splat) on the CPU, forward
only.

The authors' ``render`` calls it under ``torch.no_grad()`` with a camera at the light::

    _, out_weight, _, shadow = GaussianRasterizer(raster_settings=settings)(
        means3D, means2D, shs=None, colors_precomp=zeros(2, 3), opacities, scales, rotations,
        cov3D_precomp=None, non_trans=zeros(N), offset=0.015, thres=4, is_train=...)

and then uses ``shadow / clamp_min(non_trans, 1e-6)`` as each Gaussian's shadow hint and
``out_weight`` to rank Gaussians for pruning. This module reproduces ``forward.cu`` of the two
pinned repositories:

- preprocessing (``preprocessCUDA``): ``p_view = [p, 1] · viewmatrix`` (3DGS's transposed layout),
  culled when ``p_view.z <= 0.2``; the 3DGS 2D covariance (Jacobian with x/z, y/z clamped to
  ±1.3·tan(fov/2), focal lengths ``W / (2 tanfovx)``, ``H / (2 tanfovy)``, + 0.3 px² on the
  diagonal), skipped if its determinant is 0; ``radius = ceil(3·sqrt(mid + sqrt(max(0.1, mid² −
  det))))``; 2D mean ``((ndc + 1)·S − 1) / 2`` from ``projmatrix`` (pixel centres at integers);
  tiles from ``getRect`` (16 px, truncating divisions), skipped when it touches none; the sort key
  ``|p_view|²`` (squared distance to the light camera's centre);
- tile lists sorted by (key, Gaussian index) as the stable radix sort of ``duplicateWithKeys``
  leaves them;
- the per-pixel loop of ``renderCUDA`` (lagging pointer, ``offset``, ``thres``, ``out_weight``): see
  ``csrc/official_light.cpp``, which runs it;
- returns ``(color, out_weight [N, 1], radii [N] int32, trans [N])`` with ``color`` the unused
  [2, 2, 2] zeros the extension returns, and adds into ``non_trans`` in place, as the extension
  does.

The two pinned ``forward.cu`` differ in one place: SSD-GS 26e4251 clamps ``power_j`` at 10
(lines 412-416, ``CLIP_THRESHOLD``), GS³ 83c8daa does not. The clamp can only act on a Gaussian
whose 2D covariance is not positive definite (otherwise ``power_j <= 0``), i.e. with a precomputed
non-PSD ``cov3D``. The variant is chosen by ``$OLATBENCH_STANDIN_LIGHT``
(set by the runner: `VARIANTS`); without it the rasterizer refuses to run.
"""

from __future__ import annotations

import ctypes
import math
import os
from pathlib import Path
from typing import NamedTuple

import torch
from torch import nn

from olatbench._native import NativeLibrary, Signature
from olatbench._native.tensors import pointer, thread_count
from olatbench.gaussians.projection import covariances_3d
from olatbench.gaussians.tiles import float_order_key
from olatbench.methods.official.cpu_standins import VARIANT_VARIABLE

BLOCK = 16  # forward.cu's BLOCK_X = BLOCK_Y
NEAR_VIEW_Z = 0.2  # in_frustum: p_view.z <= 0.2 is culled
LOW_PASS = 0.3
FRUSTUM_CLAMP = 1.3
# power_j clamp per pinned forward.cu (None: no clamp).
VARIANTS: dict[str, float | None] = {"ssdgs-26e4251": 10.0, "gs3-83c8daa": None}

_P, _INT, _F = ctypes.c_void_p, ctypes.c_int, ctypes.c_float
LIBRARY = NativeLibrary(
    "olatbench_official_light",
    [Path(__file__).parent / "csrc" / "official_light.cpp"],
    {
        "olatbench_official_light_f32": Signature(
            None, (_P, _P, _P, _P, _P, *(_INT,) * 5, _F, _F, _INT, _INT, _F, _INT, _P, _P, _P)
        ),
    },
)


class GaussianRasterizationSettings(NamedTuple):
    """As the extension's (``diff_gaussian_rasterization_light/__init__.py``)."""

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


class Preprocessed(NamedTuple):
    """``preprocessCUDA``'s outputs: ``xy`` [N, 2] px (integer pixel centres), ``depths`` [N]
    (|p_view|²), ``conic_opacity`` [N, 4], ``radii`` [N] int32 (0: skipped), ``rect`` [N, 4] int64
    (x0, y0, x1, y1) tiles, end exclusive."""

    xy: torch.Tensor
    depths: torch.Tensor
    conic_opacity: torch.Tensor
    radii: torch.Tensor
    rect: torch.Tensor


def variant_clip(variant: str | None = None) -> float | None:
    """The ``power_j`` clamp of ``variant`` (default ``$OLATBENCH_STANDIN_LIGHT``); ValueError if
    unknown."""
    name = variant if variant is not None else os.environ.get(VARIANT_VARIABLE)
    if name not in VARIANTS:
        raise ValueError(
            f"diff_gaussian_rasterization_light stand-in: {VARIANT_VARIABLE}={name!r} names no "
            f"known forward.cu; known: {', '.join(VARIANTS)} (the runner sets it for device=cpu "
            "jobs)"
        )
    return VARIANTS[name]


def preprocess(
    means3D: torch.Tensor,
    opacities: torch.Tensor,
    scales: torch.Tensor | None,
    rotations: torch.Tensor | None,
    cov3D: torch.Tensor | None,
    settings: GaussianRasterizationSettings,
) -> Preprocessed:
    """forward.cu's ``preprocessCUDA`` in float32 (module docstring); ``cov3D`` [N, 6]
    (xx, xy, xz, yy, yz, zz) replaces ``scales``/``rotations`` when given."""
    f32 = torch.float32
    means = means3D.detach().to(f32)
    n = means.shape[0]
    view = settings.viewmatrix.detach().to(f32)
    proj = settings.projmatrix.detach().to(f32)
    width, height = int(settings.image_width), int(settings.image_height)
    tanx, tany = float(settings.tanfovx), float(settings.tanfovy)
    hom = torch.cat([means, torch.ones(n, 1, dtype=f32)], dim=1)
    p_view = hom @ view[:, :3]
    p_hom = hom @ proj
    p_proj = p_hom[:, :3] * (1.0 / (p_hom[:, 3:] + 1e-7))
    if cov3D is None:
        sigma = covariances_3d(
            rotations.detach().to(f32), scales.detach().to(f32) * settings.scale_modifier
        )
    else:
        c = cov3D.detach().to(f32)
        sigma = torch.stack([c[:, [0, 1, 2]], c[:, [1, 3, 4]], c[:, [2, 4, 5]]], dim=1)
    focal_x, focal_y = width / (2.0 * tanx), height / (2.0 * tany)
    tz = p_view[:, 2]
    tx = (p_view[:, 0] / tz).clamp(-FRUSTUM_CLAMP * tanx, FRUSTUM_CLAMP * tanx) * tz
    ty = (p_view[:, 1] / tz).clamp(-FRUSTUM_CLAMP * tany, FRUSTUM_CLAMP * tany) * tz
    zeros = torch.zeros_like(tz)
    jac = torch.stack(
        [
            torch.stack([focal_x / tz, zeros, -(focal_x * tx) / (tz * tz)], -1),
            # [N, 2, 3]
            torch.stack([zeros, focal_y / tz, -(focal_y * ty) / (tz * tz)], -1),
        ],
        dim=1,
    )
    rot = view[:3, :3].T  # world -> view for column vectors
    cov = jac @ (rot @ sigma @ rot.T) @ jac.transpose(1, 2)
    a, b, cc = cov[:, 0, 0] + LOW_PASS, cov[:, 0, 1], cov[:, 1, 1] + LOW_PASS
    det = a * cc - b * b
    inv = 1.0 / torch.where(det == 0, torch.ones_like(det), det)
    conic = torch.stack([cc * inv, -b * inv, a * inv], dim=1)
    mid = 0.5 * (a + cc)
    root = torch.sqrt(torch.clamp(mid * mid - det, min=0.1))
    radius = torch.ceil(3.0 * torch.sqrt(torch.maximum(mid + root, mid - root)))
    xy = torch.stack(
        [((p_proj[:, 0] + 1.0) * width - 1.0) * 0.5, ((p_proj[:, 1] + 1.0) * height - 1.0) * 0.5], 1
    )
    grid = torch.tensor([(width + BLOCK - 1) // BLOCK, (height + BLOCK - 1) // BLOCK])
    finite = torch.isfinite(xy).all(1) & torch.isfinite(radius)
    r = torch.where(finite, radius, zeros)[:, None]
    xy_safe = torch.where(finite[:, None], xy, torch.zeros_like(xy))
    rect_min = torch.minimum(torch.trunc((xy_safe - r) / BLOCK).clamp(min=0).long(), grid)
    rect_max = torch.minimum(
        torch.trunc((xy_safe + r + BLOCK - 1) / BLOCK).clamp(min=0).long(), grid
    )
    area = (rect_max - rect_min).prod(dim=1)
    keep = (tz > NEAR_VIEW_Z) & (det != 0) & (area != 0) & finite
    radii = torch.where(keep, radius, zeros).to(torch.int32)
    depths = p_view[:, 2] * p_view[:, 2] + p_view[:, 1] * p_view[:, 1] + p_view[:, 0] * p_view[:, 0]
    conic_opacity = torch.cat([conic, opacities.detach().to(f32).reshape(n, 1)], dim=1)
    rect = torch.where(
        keep[:, None], torch.cat([rect_min, rect_max], dim=1), torch.zeros(n, 4, dtype=torch.long)
    )
    return Preprocessed(xy=xy, depths=depths, conic_opacity=conic_opacity, radii=radii, rect=rect)


def tile_lists(
    pre: Preprocessed, width: int, height: int
) -> tuple[torch.Tensor, torch.Tensor, int, int]:
    """(offsets [tiles + 1], Gaussian ids): each tile's Gaussians sorted by depth, ties by index
    (the stable sort of ``duplicateWithKeys``' keys), and the grid size (tiles_x, tiles_y)."""
    tiles_x, tiles_y = (width + BLOCK - 1) // BLOCK, (height + BLOCK - 1) // BLOCK
    x0, y0, x1, y1 = pre.rect.unbind(1)
    span = (x1 - x0).clamp(min=0)
    counts = span * (y1 - y0).clamp(min=0)
    gauss = torch.repeat_interleave(torch.arange(pre.rect.shape[0]), counts)
    local = torch.arange(gauss.numel()) - (torch.cumsum(counts, 0) - counts)[gauss]
    tile_y = y0[gauss] + torch.div(local, span[gauss], rounding_mode="floor")
    tile_x = x0[gauss] + local - (tile_y - y0[gauss]) * span[gauss]
    tile_ids = tile_y * tiles_x + tile_x
    order = torch.sort((tile_ids << 32) | float_order_key(pre.depths[gauss]), stable=True).indices
    offsets = torch.zeros(tiles_x * tiles_y + 1, dtype=torch.int64)
    offsets[1:] = torch.cumsum(torch.bincount(tile_ids, minlength=tiles_x * tiles_y), 0)
    return offsets, gauss[order].contiguous(), tiles_x, tiles_y


@torch.no_grad()
def light_splat(
    means3D: torch.Tensor,
    opacities: torch.Tensor,
    scales: torch.Tensor | None,
    rotations: torch.Tensor | None,
    cov3D: torch.Tensor | None,
    settings: GaussianRasterizationSettings,
    non_trans: torch.Tensor,
    offset: float,
    thres: float,
    is_train: bool,
    clip: float | None,
    threads: int | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(out_weight [N, 1], radii [N] int32, trans [N]) of forward.cu; adds into ``non_trans`` [N] in
    place."""
    n = means3D.shape[0]
    width, height = int(settings.image_width), int(settings.image_height)
    out_trans = torch.zeros(n, dtype=torch.float32)
    out_weight = torch.zeros(n, dtype=torch.float32)
    non_sum = torch.zeros(n, dtype=torch.float32)
    if n == 0:
        return out_weight[:, None], torch.zeros(0, dtype=torch.int32), out_trans
    pre = preprocess(means3D, opacities, scales, rotations, cov3D, settings)
    offsets, ids, tiles_x, tiles_y = tile_lists(pre, width, height)
    xy, depths, conic_opacity = (t.contiguous() for t in (pre.xy, pre.depths, pre.conic_opacity))
    LIBRARY.load()["olatbench_official_light_f32"](
        pointer(xy),
        pointer(depths),
        pointer(conic_opacity),
        pointer(offsets),
        pointer(ids),
        width,
        height,
        BLOCK,
        tiles_x,
        tiles_y,
        float(offset),
        float(thres),
        int(bool(is_train)),
        int(clip is not None),
        float(clip if clip is not None else math.inf),
        thread_count(threads),
        pointer(out_trans),
        pointer(non_sum),
        pointer(out_weight),
    )
    non_trans.add_(non_sum.to(non_trans.dtype))
    return out_weight[:, None], pre.radii, out_trans


class GaussianRasterizer(nn.Module):
    """The extension's ``GaussianRasterizer`` (forward only); the forward.cu variant from
    `variant_clip`."""

    def __init__(self, raster_settings: GaussianRasterizationSettings) -> None:
        super().__init__()
        self.raster_settings = raster_settings
        self.clip = variant_clip()

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
        non_trans=None,
        offset=0.015,
        thres=4.0,
        is_train=False,
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
        if torch.is_grad_enabled() and any(
            t is not None and t.requires_grad
            for t in (means3D, opacities, scales, rotations, cov3D_precomp)
        ):
            raise NotImplementedError(
                "diff_gaussian_rasterization_light stand-in (olatbench CPU): forward only; "
                "call it under torch.no_grad() as the authors' render does"
            )
        if non_trans is None:
            raise ValueError(
                "diff_gaussian_rasterization_light stand-in: non_trans (the [N] accumulator) is "
                "needed"
            )
        out_weight, radii, trans = light_splat(
            means3D,
            opacities,
            scales,
            rotations,
            cov3D_precomp,
            self.raster_settings,
            non_trans,
            offset,
            thres,
            is_train,
            self.clip,
        )
        # the extension's placeholder: the light pass renders no colour
        color = torch.zeros(2, 2, 2)
        return color, out_weight, radii, trans
