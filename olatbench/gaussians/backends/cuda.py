"""CUDA backend: gsplat's ``rasterize_to_pixels`` fed with olatbench's own tile bins.

Written against gsplat's documented API (``gsplat.rasterize_to_pixels(means2d [C,N,2], conics [C,N,3],
colors [C,N,D], opacities [C,N], image_width, image_height, tile_size, isect_offsets [C,th,tw],
flatten_ids [M], backgrounds=None) -> (colours [C,H,W,D], alphas [C,H,W,1])``) with one camera (C = 1).
gsplat uses the same pixel-centre (+0.5) and conic conventions; its alpha clamp is 0.999 instead of 0.99 and
its backward is its own, so results differ slightly from the cpu/torch backends. It cannot run on the
development machine (no GPU): only its selection logic is tested there.
"""

from __future__ import annotations

import importlib.util

import torch

from ..tiles import TileBins


def gsplat_available() -> bool:
    """True when gsplat is importable and a CUDA device is present."""
    return importlib.util.find_spec("gsplat") is not None and torch.cuda.is_available()


def rasterize_cuda(
    means2d: torch.Tensor,
    conics: torch.Tensor,
    opacities: torch.Tensor,
    features: torch.Tensor,
    bins: TileBins,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Same contract as ``torch_ref.rasterize_torch``, on CUDA tensors through gsplat."""
    from gsplat import rasterize_to_pixels

    isect_offsets = bins.offsets[:-1].to(device=means2d.device, dtype=torch.int32)
    colours, alphas = rasterize_to_pixels(
        means2d=means2d[None],
        conics=conics[None],
        colors=features[None],
        opacities=opacities[None],
        image_width=bins.width,
        image_height=bins.height,
        tile_size=bins.tile_size,
        isect_offsets=isect_offsets.reshape(1, bins.tiles_y, bins.tiles_x),
        flatten_ids=bins.gaussian_ids.to(device=means2d.device, dtype=torch.int32),
    )
    return colours[0], 1.0 - alphas[0, ..., 0]


__all__ = ["gsplat_available", "rasterize_cuda"]
