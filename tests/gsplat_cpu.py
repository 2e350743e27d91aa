"""gsplat's own torch rasterizer, made to run on the CPU for the convention tests.

``gsplat.cuda._torch_impl._rasterize_to_pixels`` is gsplat's pure-torch twin of its CUDA
``rasterize_to_pixels`` (same signature; gsplat's ``tests/test_basic.py`` checks the two against
each other). Its compositing maths (pixel centre ``+0.5``, ``sigma = ½ dᵀ conic d``, ``alpha =
min(0.999, o·exp(-sigma))``) is in ``accumulate`` and runs here unchanged, but two of its helpers do
not run without CUDA:

- ``gsplat.cuda._wrapper.rasterize_to_indices_in_range`` launches the CUDA kernel
  ``RasterizeToIndices3DGS.cu``;
- ``accumulate`` imports ``nerfacc`` (``render_weight_from_alpha``, ``accumulate_along_rays``), a
  CUDA extension package that is not installed here.

`indices_in_range` ports that kernel to torch statement by statement (read from the installed
wheel's ``csrc/RasterizeToIndices3DGS.cu``) and `fake_nerfacc` provides the two nerfacc functions
for sorted ray indices. `cpu_gsplat(monkeypatch)` installs both and points
``gsplat.rasterize_to_pixels`` at the torch twin, so that
``olatbench.gaussians.backends.cuda.rasterize_cuda`` runs gsplat's code on CPU tensors
(any float dtype).
"""

from __future__ import annotations

import types

import pytest
import torch

gsplat = pytest.importorskip("gsplat")
gsplat_wrapper = pytest.importorskip("gsplat.cuda._wrapper")
gsplat_torch = pytest.importorskip("gsplat.cuda._torch_impl")

# Constants of gsplat's kernels (csrc/Common.h ALPHA_THRESHOLD, the 0.999 clamp and the 1e-4 stop in
# the kernels).
ALPHA_THRESHOLD = 1.0 / 255.0
ALPHA_CLAMP = 0.999
T_STOP = 1e-4


def indices_in_range(
    range_start: int,
    range_end: int,
    transmittances: torch.Tensor,
    means2d: torch.Tensor,
    conics: torch.Tensor,
    opacities: torch.Tensor,
    image_width: int,
    image_height: int,
    tile_size: int,
    isect_offsets: torch.Tensor,
    flatten_ids: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Torch port of ``rasterize_to_indices_in_range`` (one image: ``means2d`` (1, N, 2) etc.).

    For each pixel (centre ``(j + 0.5, i + 0.5)``) of each tile, walk the tile's Gaussians in the
    batches ``[range_start, range_end)`` of ``tile_size²`` entries front to back from the pixel's
    current transmittance; skip a pair when ``sigma < 0`` or ``alpha < 1/255``; stop (exclusive) at
    the first pair whose next transmittance is ``<= 1e-4``. Returns (Gaussian ids, row-major pixel
    ids, image ids) of the kept pairs, grouped by pixel in row-major order and front to back within
    a pixel, as the kernel's two passes write them."""
    if means2d.shape[0] != 1:
        raise ValueError("the port handles one image")
    tiles_y, tiles_x = isect_offsets.shape[-2:]
    offsets = isect_offsets.reshape(-1).to(torch.int64)
    n_isects = flatten_ids.numel()
    block = tile_size * tile_size
    found_pixels, found_orders, found_ids = [], [], []
    with torch.no_grad():
        for tile in range(tiles_y * tiles_x):
            start = int(offsets[tile])
            end = n_isects if tile == tiles_y * tiles_x - 1 else int(offsets[tile + 1])
            lo, hi = start + block * range_start, min(end, start + block * range_end)
            if lo >= hi:
                continue
            ids = flatten_ids[lo:hi].to(torch.int64)
            ty, tx = divmod(tile, tiles_x)
            rows = torch.arange(ty * tile_size, min((ty + 1) * tile_size, image_height))
            cols = torch.arange(tx * tile_size, min((tx + 1) * tile_size, image_width))
            ii, jj = torch.meshgrid(rows, cols, indexing="ij")
            ii, jj = ii.reshape(-1), jj.reshape(-1)
            px = jj.to(means2d.dtype) + 0.5
            py = ii.to(means2d.dtype) + 0.5
            xy, conic, opac = means2d[0, ids], conics[0, ids], opacities[0, ids]
            dx = xy[None, :, 0] - px[:, None]
            dy = xy[None, :, 1] - py[:, None]
            sigma = (
                0.5 * (conic[None, :, 0] * dx * dx + conic[None, :, 2] * dy * dy)
                + conic[None, :, 1] * dx * dy
            )
            alpha = (opac[None, :] * torch.exp(-sigma)).clamp(max=ALPHA_CLAMP)
            used = ~((sigma < 0) | (alpha < ALPHA_THRESHOLD))
            trans = transmittances[0, ii, jj]
            next_trans = trans[:, None] * torch.cumprod(
                torch.where(used, 1.0 - alpha, torch.ones_like(alpha)), 1
            )
            # transmittance only falls: the first stop ends the pixel
            keep = used & (next_trans > T_STOP)
            pixel, order = torch.nonzero(keep, as_tuple=True)
            found_pixels.append(ii[pixel] * image_width + jj[pixel])
            found_orders.append(order)
            found_ids.append(ids[order])
    if not found_ids:
        empty = torch.zeros(0, dtype=torch.int64)
        return empty, empty, empty
    pixels, orders, ids = (torch.cat(t) for t in (found_pixels, found_orders, found_ids))
    rank = torch.argsort(pixels * (orders.max() + 1) + orders, stable=True)
    return ids[rank], pixels[rank], torch.zeros_like(pixels)


def _render_weight_from_alpha(
    alphas: torch.Tensor, ray_indices: torch.Tensor, n_rays: int
) -> tuple[torch.Tensor, torch.Tensor]:
    """nerfacc: per ray (sorted ``ray_indices``), exclusive transmittance T_i = Π_{j<i}(1 - α_j),
    weights T_i α_i."""
    del n_rays
    _, counts = torch.unique_consecutive(ray_indices, return_counts=True)
    trans = (
        torch.cat(
            [
                torch.cumprod(torch.cat([a.new_ones(1), 1.0 - a[:-1]]), 0)
                for a in torch.split(alphas, counts.tolist())
            ]
        )
        if alphas.numel()
        else alphas
    )
    return trans * alphas, trans


def _accumulate_along_rays(
    weights: torch.Tensor, values: torch.Tensor | None, ray_indices: torch.Tensor, n_rays: int
) -> torch.Tensor:
    """nerfacc: Σ_i w_i v_i per ray (``values`` None: Σ_i w_i), shape (n_rays, C)."""
    src = weights[:, None] if values is None else weights[:, None] * values
    return src.new_zeros(n_rays, src.shape[1]).index_add(0, ray_indices, src)


fake_nerfacc = types.ModuleType("nerfacc")
fake_nerfacc.render_weight_from_alpha = _render_weight_from_alpha
fake_nerfacc.accumulate_along_rays = _accumulate_along_rays


def cpu_gsplat(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make ``gsplat.rasterize_to_pixels`` gsplat's torch twin, runnable on CPU tensors
    (see the module doc)."""
    monkeypatch.setitem(__import__("sys").modules, "nerfacc", fake_nerfacc)
    monkeypatch.setattr(gsplat_wrapper, "rasterize_to_indices_in_range", indices_in_range)
    monkeypatch.setattr(gsplat, "rasterize_to_pixels", gsplat_torch._rasterize_to_pixels)
