"""16×16 tile binning of screen-space Gaussians (the 3DGS duplicate-and-sort step), in torch.

Each Gaussian is duplicated once per tile its screen-space box touches. Every (tile, Gaussian) pair
gets the 64-bit key ``tile_id << 32 | order(depth)`` where ``order`` maps a float32 to a 32-bit
integer with the same order; one stable sort of the keys groups pairs by tile and orders each tile's
list front to back (ties keep Gaussian index order, so the binning is deterministic).
``offsets[t]:offsets[t+1]`` then indexes tile ``t``'s slice of ``gaussian_ids``. Both the torch
reference and the C++ backend consume these bins.

Two implementations give identical bins: the torch one below (any device; the reference) and the C++
one of :mod:`olatbench.gaussians.backends.cpu` (per-tile counting, then one sort of packed
(key, index) pairs per tile; 1.5–3.5× faster on the CPU). ``backend="auto"`` uses the C++ one
whenever the rasterizer would.

A Gaussian with 2D mean m and radius r covers the pixels whose centres (x + 0.5) lie in
[m - r, m + r].
"""

from __future__ import annotations

import torch

from .backends import resolve_kernel_backend
from .backends.cpu import bin_gaussians_cpu
from .host_sync import allowed_host_sync
from .screen import TILE_SIZE, TileBins


def pixel_ranges(
    means2d: torch.Tensor, radii: torch.Tensor, width: int, height: int
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Inclusive pixel box (x0, x1, y0, y1) clipped to the image, and a (N,) bool "non-empty"
    mask."""
    m = means2d.detach()
    r = radii.to(m.dtype)
    x0 = torch.ceil(m[:, 0] - r - 0.5)
    x1 = torch.floor(m[:, 0] + r - 0.5)
    y0 = torch.ceil(m[:, 1] - r - 0.5)
    y1 = torch.floor(m[:, 1] + r - 0.5)
    inside = (
        (radii > 0)
        & (x0 <= x1)
        & (y0 <= y1)
        & (x1 >= 0)
        & (x0 <= width - 1)
        & (y1 >= 0)
        & (y0 <= height - 1)
    )
    inside &= torch.isfinite(m).all(dim=-1)
    x0, x1 = (t.clamp(0, width - 1).to(torch.int64) for t in (x0, x1))
    y0, y1 = (t.clamp(0, height - 1).to(torch.int64) for t in (y0, y1))
    return x0, x1, y0, y1, inside


def float_order_key(values: torch.Tensor) -> torch.Tensor:
    """Map values (as float32) to int64 in [0, 2³²) with the same order
    (for packing into sort keys)."""
    bits = values.detach().to(torch.float32).contiguous().view(torch.int32).to(torch.int64)
    # Negative floats: flip the magnitude bits so that larger magnitude sorts first; then shift to
    # unsigned.
    flipped = torch.where(bits < 0, bits ^ 0x7FFFFFFF, bits)
    return flipped + (1 << 31)


def bin_gaussians(
    means2d: torch.Tensor,
    radii: torch.Tensor,
    sort_keys: torch.Tensor,
    width: int,
    height: int,
    tile_size: int = TILE_SIZE,
    backend: str = "auto",
) -> TileBins:
    """Bin Gaussians (means2d (N, 2) px, radii (N,) px, 0 = culled) into tiles, each list sorted by
    ``sort_keys`` (N,) ascending (camera depth for rendering, squared distance for the light pass).

    ``backend``: "torch", "cpu" (the C++ kernel; CPU float32/float64 means) or "auto" (the
    rasterizer's choice for these tensors, see :func:`olatbench.gaussians.backends.resolve_backend`;
    torch unless "cpu")."""
    if resolve_kernel_backend(backend, means2d.device, means2d.dtype, "binning") == "cpu":
        return bin_gaussians_cpu(means2d, radii, sort_keys, width, height, tile_size)
    x0, x1, y0, y1, inside = pixel_ranges(means2d, radii, width, height)
    tile_ranges = (x0 // tile_size, x1 // tile_size + 1, y0 // tile_size, y1 // tile_size + 1)
    return bins_of_tile_ranges(tile_ranges, inside, sort_keys, width, height, tile_size)


def bins_of_tile_ranges(
    tile_ranges: tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor],
    inside: torch.Tensor,
    sort_keys: torch.Tensor,
    width: int,
    height: int,
    tile_size: int = TILE_SIZE,
) -> TileBins:
    """The torch binning of `bin_gaussians` from given per-Gaussian tile ranges
    ``(tx0, tx1, ty0, ty1)`` (N,) int64 each, ``[tx0, tx1) × [ty0, ty1)`` inside the tile grid, for
    the Gaussians with ``inside`` (N,) bool."""
    tx0, tx1, ty0, ty1 = tile_ranges
    device = inside.device
    tiles_x = (width + tile_size - 1) // tile_size
    tiles_y = (height + tile_size - 1) // tile_size
    span_x = tx1 - tx0
    counts = torch.where(inside, span_x * (ty1 - ty0), torch.zeros_like(span_x))
    with allowed_host_sync("tile-intersections"):  # the list's length: the one host read of a pass
        total = int(counts.sum())
    gauss = torch.repeat_interleave(
        torch.arange(inside.shape[0], device=device), counts, output_size=total
    )
    first = torch.cumsum(counts, 0) - counts
    # One gather of all per-Gaussian quantities the pairs need (cheaper than one gather each).
    per_pair = torch.stack([tx0, ty0, span_x, first, float_order_key(sort_keys)], dim=1)[gauss]
    local = torch.arange(total, device=device) - per_pair[:, 3]
    tile_y = per_pair[:, 1] + torch.div(local, per_pair[:, 2], rounding_mode="floor")
    tile_x = per_pair[:, 0] + local - (tile_y - per_pair[:, 1]) * per_pair[:, 2]
    tile_ids = tile_y * tiles_x + tile_x
    keys = (tile_ids << 32) | per_pair[:, 4]
    sorted_keys, order = torch.sort(keys, stable=True)
    gaussian_ids = gauss[order]
    # Tile t's list starts at the number of pairs of the tiles before it: a search of the sorted
    # tile ids (a bincount would size its output from the values, a host sync on a GPU).
    tiles = torch.arange(tiles_x * tiles_y + 1, device=device)
    offsets = torch.searchsorted(sorted_keys >> 32, tiles)
    return TileBins(
        offsets=offsets,
        gaussian_ids=gaussian_ids,
        tile_size=tile_size,
        tiles_x=tiles_x,
        tiles_y=tiles_y,
        width=int(width),
        height=int(height),
    )


__all__ = [
    "TILE_SIZE",
    "TileBins",
    "bin_gaussians",
    "bins_of_tile_ranges",
    "float_order_key",
    "pixel_ranges",
]
