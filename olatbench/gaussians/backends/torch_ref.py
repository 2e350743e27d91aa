"""Reference rasterizer in plain torch: the test oracle, on any device and dtype.

Tile-based and vectorised: the non-empty tiles are grouped into chunks (longest lists first, so
padding stays small) and each chunk evaluates every (pixel, Gaussian-of-its-tile) pair at once.
Front-to-back compositing follows the given `CompositingRules` exactly (default 3DGS's: ``alpha =
min(0.99, o·exp(power))`` with ``power = -½ dᵀ conic d`` (d = mean - pixel centre), pairs with
``power > 0`` or ``alpha < 1/255`` are skipped, and a pixel stops *before* the Gaussian that would
bring its transmittance below 1e-4; gsplat's: 0.999 and at or below 1e-4). Gradients come from
autograd (the true gradient: zero where the alpha clamp is active). With autograd on, each chunk is
wrapped in activation checkpointing so the memory held for backward is one chunk's worth, not the
whole image's.
"""

from __future__ import annotations

from collections.abc import Iterator

import torch
from torch.utils.checkpoint import checkpoint

from ..compositing import ALPHA_MIN, T_MIN, THREE_DGS, CompositingRules
from ..screen import TileBins

ALPHA_MAX = THREE_DGS.alpha_max  # the default rules' clamp
# Elements (pixels × padded list length) evaluated per chunk; bounds peak memory
# (~10 tensors of this size).
CHUNK_ELEMENTS = 1 << 22


def _chunk_weights(
    means2d: torch.Tensor,
    conics: torch.Tensor,
    opacities: torch.Tensor,
    ids: torch.Tensor,
    valid: torch.Tensor,
    pixels: torch.Tensor,
    rules: CompositingRules = THREE_DGS,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Blending weights of B tiles: ``ids``/``valid`` (B, L) padded lists, ``pixels`` (B, P, 2)
    pixel centres.

    Returns the weights ``T·α`` (B, P, L) (0 where a Gaussian is skipped or after the pixel stops),
    ``1 - α`` (B, P, L) and the composited mask (B, P, L)."""
    mean = means2d[ids]  # (B, L, 2)
    con = conics[ids]
    d = mean[:, None, :, :] - pixels[:, :, None, :]  # (B, P, L, 2)
    dx, dy = d[..., 0], d[..., 1]
    a, b, c = (con[:, None, :, k] for k in range(3))
    power = -0.5 * (a * dx * dx + c * dy * dy) - b * dx * dy
    alpha = (opacities[ids][:, None, :] * torch.exp(power)).clamp(max=rules.alpha_max)
    keep = valid[:, None, :] & (power <= 0) & (alpha >= ALPHA_MIN)
    alpha = torch.where(keep, alpha, torch.zeros_like(alpha))
    one_minus = 1.0 - alpha
    t_after = torch.cumprod(one_minus, dim=-1)
    t_before = torch.cat([torch.ones_like(t_after[..., :1]), t_after[..., :-1]], dim=-1)
    include = (t_after > T_MIN if rules.stop_at_t_min else t_after >= T_MIN).detach()
    weights = torch.where(include, t_before * alpha, torch.zeros_like(alpha))
    return weights, one_minus, include


def _composite_chunk(
    means2d: torch.Tensor,
    conics: torch.Tensor,
    opacities: torch.Tensor,
    features: torch.Tensor,
    ids: torch.Tensor,
    valid: torch.Tensor,
    pixels: torch.Tensor,
    rules: CompositingRules = THREE_DGS,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Composite B tiles (arguments as `_chunk_weights`, ``features`` (N, C)).

    Returns colour without background (B, P, C) and final transmittance (B, P)."""
    weights, one_minus, include = _chunk_weights(
        means2d, conics, opacities, ids, valid, pixels, rules
    )
    colour = torch.einsum("bpl,blc->bpc", weights, features[ids])
    t_final = torch.where(include, one_minus, torch.ones_like(one_minus)).prod(dim=-1)
    return colour, t_final


def _chunks(counts: torch.Tensor, pixels_per_tile: int) -> list[torch.Tensor]:
    """Group non-empty tiles (longest list first) into chunks of at most CHUNK_ELEMENTS padded
    elements."""
    order = torch.argsort(counts, descending=True, stable=True)
    order = order[counts[order] > 0].tolist()
    counts_list = counts.tolist()
    chunks, current, longest = [], [], 0
    for tile in order:
        longest_if_added = max(longest, counts_list[tile])
        if current and (len(current) + 1) * longest_if_added * pixels_per_tile > CHUNK_ELEMENTS:
            chunks.append(torch.tensor(current, dtype=torch.int64, device="cpu"))
            current, longest_if_added = [], counts_list[tile]
        current.append(tile)
        longest = longest_if_added
    if current:
        chunks.append(torch.tensor(current, dtype=torch.int64, device="cpu"))
    return chunks


def _chunk_lists(
    bins: TileBins, chunks: list[torch.Tensor], device: torch.device, dtype: torch.dtype
) -> Iterator[tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]]:
    """Per chunk of tiles: their indices (B,), padded Gaussian lists ``ids``/``valid`` (B, L) and
    the pixel centres (B, P, 2) of their ``tile_size``² pixels (including those of edge tiles beyond
    the image)."""
    ts = bins.tile_size
    offsets = bins.offsets.to(device)
    ids_all = bins.gaussian_ids.to(device)
    counts = offsets[1:] - offsets[:-1]
    local = torch.arange(ts * ts, device=device)
    # (P, 2) offsets within a tile
    tile_pixel = torch.stack([local % ts, local // ts], dim=-1).to(dtype) + 0.5
    for chunk in chunks:
        chunk_dev = chunk.to(device)
        starts = offsets[chunk_dev]
        lengths = counts[chunk_dev]
        width = int(lengths.max())
        slot = torch.arange(width, device=device)
        valid = slot[None, :] < lengths[:, None]
        ids = ids_all[(starts[:, None] + slot[None, :]).clamp(max=max(ids_all.numel() - 1, 0))]
        ids = torch.where(valid, ids, torch.zeros_like(ids))
        origin = (
            torch.stack([chunk_dev % bins.tiles_x, chunk_dev // bins.tiles_x], dim=-1).to(dtype)
            * ts
        )
        yield chunk_dev, ids, valid, origin[:, None, :] + tile_pixel[None, :, :]


def rasterize_torch(
    means2d: torch.Tensor,
    conics: torch.Tensor,
    opacities: torch.Tensor,
    features: torch.Tensor,
    bins: TileBins,
    rules: CompositingRules = THREE_DGS,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Composite binned Gaussians: colour without background (H, W, C) and final transmittance
    (H, W).

    Inputs: means2d (N, 2) px, conics (N, 3), opacities (N,), features (N, C), all one dtype and
    device; ``rules``: the clamp and stop (`olatbench.gaussians.compositing`)."""
    device, dtype = means2d.device, means2d.dtype
    ts, n_tiles, channels = bins.tile_size, bins.num_tiles, features.shape[1]
    counts = (bins.offsets[1:] - bins.offsets[:-1]).cpu()
    use_checkpoint = torch.is_grad_enabled() and any(
        t.requires_grad for t in (means2d, conics, opacities, features)
    )

    colour_tiles = torch.zeros(n_tiles, ts * ts, channels, device=device, dtype=dtype)
    t_tiles = torch.ones(n_tiles, ts * ts, device=device, dtype=dtype)
    chunks = _chunks(counts, ts * ts)
    if not chunks and use_checkpoint:
        # Nothing visible: keep the outputs connected to the inputs (zero gradients) so that
        # backward works on an empty view, as with the other backends.
        tie = sum(t.sum() for t in (means2d, conics, opacities, features)) * 0
        colour_tiles, t_tiles = colour_tiles + tie, t_tiles + tie
    for chunk_dev, ids, valid, pixels in _chunk_lists(bins, chunks, device, dtype):
        args = (means2d, conics, opacities, features, ids, valid, pixels, rules)
        if use_checkpoint:
            colour, t_final = checkpoint(_composite_chunk, *args, use_reentrant=False)
        else:
            colour, t_final = _composite_chunk(*args)
        colour_tiles = colour_tiles.index_copy(0, chunk_dev, colour)
        t_tiles = t_tiles.index_copy(0, chunk_dev, t_final)

    def untile(x: torch.Tensor) -> torch.Tensor:
        x = x.reshape(bins.tiles_y, bins.tiles_x, ts, ts, *x.shape[2:]).transpose(1, 2)
        x = x.reshape(bins.tiles_y * ts, bins.tiles_x * ts, *x.shape[4:])
        return x[: bins.height, : bins.width]

    return untile(colour_tiles), untile(t_tiles)


@torch.no_grad()
def max_weights_torch(
    means2d: torch.Tensor, conics: torch.Tensor, opacities: torch.Tensor, bins: TileBins
) -> torch.Tensor:
    """Each Gaussian's largest blending weight ``T·α`` over the image's pixels (N,) (0 for a
    Gaussian that is composited nowhere), with the compositing rules of `rasterize_torch`; inputs as
    there, no features."""
    device, dtype = means2d.device, means2d.dtype
    counts = (bins.offsets[1:] - bins.offsets[:-1]).cpu()
    best = torch.zeros(means2d.shape[0], device=device, dtype=dtype)
    for _, ids, valid, pixels in _chunk_lists(
        bins, _chunks(counts, bins.tile_size**2), device, dtype
    ):
        weights = _chunk_weights(means2d, conics, opacities, ids, valid, pixels)[0]
        # edge tiles reach past the image
        inside = (pixels[..., 0] < bins.width) & (pixels[..., 1] < bins.height)
        # (B, L)
        per_pair = torch.where(inside[:, :, None], weights, torch.zeros_like(weights)).amax(dim=1)
        best = best.scatter_reduce(0, ids[valid], per_pair[valid], reduce="amax")
    return best


__all__ = [
    "ALPHA_MAX",
    "ALPHA_MIN",
    "CHUNK_ELEMENTS",
    "T_MIN",
    "max_weights_torch",
    "rasterize_torch",
]
