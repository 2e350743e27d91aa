"""C++/OpenMP CPU backend: ``gaussians/csrc/rasterize.cpp`` called through ctypes, wrapped in
``torch.autograd.Function``s: rasterizer, projection, binning and the light pass.

The rasterizer has a hand-written backward (the 3DGS one: back-to-front per pixel, recovering each
Gaussian's transmittance from the final one) and is deterministic whatever the thread count. float32
and float64 are both supported (float64 is what the tests compare against the torch reference at
tight tolerances). ``LIBRARY`` is the Gaussian core's native library and its typed symbol table
(built on first use by ``olatbench._native``).
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from pathlib import Path

import torch

from olatbench._native import NativeLibrary, Signature, per_float
from olatbench._native.tensors import float_suffix, pointer, thread_count

from ..compositing import THREE_DGS, CompositingRules
from ..screen import RADIUS_SIGMAS, TILE_SIZE, TileBins, frustum_clamp_bounds

CSRC = Path(__file__).parents[1] / "csrc"
# a pointer (tensor data or NULL), int, int64_t
_P, _INT, _I64 = ctypes.c_void_p, ctypes.c_int, ctypes.c_int64
_GRID = (_INT,) * 5  # width, height, tile size, tiles_x, tiles_y


def _symbols(suffix: str, real: type) -> dict[str, Signature]:
    """The exported functions of ``csrc/rasterize.cpp`` for one float type
    (its ``OLATBENCH_DEFINE``)."""
    return {
        # means2d, conics, opacities, features, channels, offsets, ids, grid, threads -> colour,
        # final T, counts (then the compositing rules: alpha_max, stop_at_t_min)
        f"olatbench_forward_{suffix}": Signature(
            None, (_P, _P, _P, _P, _INT, _P, _P, *_GRID, _INT, ctypes.c_double, _INT, _P, _P, _P)
        ),
        # ... as forward, final T, counts, grad colour, grad T, N -> grads of means2d, conics,
        # opacities, features
        f"olatbench_backward_{suffix}": Signature(
            None,
            (
                _P,
                _P,
                _P,
                _P,
                _INT,
                _P,
                _P,
                *_GRID,
                _INT,
                ctypes.c_double,
                _INT,
                _P,
                _P,
                _P,
                _P,
                _I64,
                _P,
                _P,
                _P,
                _P,
            ),
        ),
        # means2d, conics, opacities, offsets, ids, grid, threads, N -> largest blending weight per
        # Gaussian
        f"olatbench_max_weight_{suffix}": Signature(
            None, (_P, _P, _P, _P, _P, *_GRID, _INT, _I64, _P)
        ),
        # means2d, conics, opacities, keys, depth_offset, density, offsets, ids, grid, radius_px,
        # threads, N -> vis_sum, count, norm, weight
        f"olatbench_shadow_gather_{suffix}": Signature(
            None,
            (
                _P,
                _P,
                _P,
                _P,
                ctypes.c_double,
                _INT,
                _P,
                _P,
                *_GRID,
                real,
                _INT,
                _I64,
                _P,
                _P,
                _P,
                _P,
            ),
        ),
        # means2d, radii, N, grid -> ranges, offsets; returns the number of (tile, Gaussian) pairs
        f"olatbench_bin_count_{suffix}": Signature(_I64, (_P, _P, _I64, *_GRID, _P, _P)),
        # ranges, keys, N, grid, offsets -> ids
        f"olatbench_bin_fill_{suffix}": Signature(None, (_P, _P, _I64, *_GRID, _P, _P)),
        # means, quats, scales, camera, N, width, height, threads -> means2d, conics, radii, depths
        f"olatbench_project_forward_{suffix}": Signature(
            None, (_P, _P, _P, _P, _I64, _INT, _INT, _INT, _P, _P, _P, _P)
        ),
        # means, quats, scales, camera, N, threads, grads of means2d, conics, depths
        # -> grads of means, quats, scales, w2c
        f"olatbench_project_backward_{suffix}": Signature(
            None, (_P, _P, _P, _P, _I64, _INT, _P, _P, _P, _P, _P, _P, _P)
        ),
    }


LIBRARY = NativeLibrary("olatbench_gaussians", [CSRC / "rasterize.cpp"], per_float(_symbols))


def _prepare(tensors: list[torch.Tensor], dtype: torch.dtype) -> list[torch.Tensor]:
    return [t.detach().to(device="cpu", dtype=dtype).contiguous() for t in tensors]


def _grid(bins: TileBins) -> tuple[int, int, int, int, int]:
    return bins.width, bins.height, bins.tile_size, bins.tiles_x, bins.tiles_y


def _suffix(dtype: torch.dtype) -> str:
    return float_suffix(dtype, "the cpu rasterizer kernels")


class _RasterizeCPU(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means2d, conics, opacities, features, offsets, ids, bins, threads, rules):
        lib = LIBRARY.load()
        dtype = means2d.dtype
        suffix = _suffix(dtype)
        means2d, conics, opacities, features = _prepare(
            [means2d, conics, opacities, features], dtype
        )
        offsets, ids = (t.to(device="cpu", dtype=torch.int64).contiguous() for t in (offsets, ids))
        channels = features.shape[1]
        colour = torch.empty(bins.height, bins.width, channels, dtype=dtype)
        final_t = torch.empty(bins.height, bins.width, dtype=dtype)
        counts = torch.empty(bins.height, bins.width, dtype=torch.int32)
        lib[f"olatbench_forward_{suffix}"](
            pointer(means2d),
            pointer(conics),
            pointer(opacities),
            pointer(features),
            channels,
            pointer(offsets),
            pointer(ids),
            *_grid(bins),
            threads,
            rules.alpha_max,
            int(rules.stop_at_t_min),
            pointer(colour),
            pointer(final_t),
            pointer(counts),
        )
        ctx.save_for_backward(means2d, conics, opacities, features, offsets, ids, final_t, counts)
        ctx.bins, ctx.threads, ctx.rules = bins, threads, rules
        ctx.mark_non_differentiable(counts)
        return colour, final_t, counts

    @staticmethod
    def backward(ctx, grad_colour, grad_t, _grad_counts):
        means2d, conics, opacities, features, offsets, ids, final_t, counts = ctx.saved_tensors
        dtype, n = means2d.dtype, means2d.shape[0]
        if grad_colour is None:
            grad_colour = torch.zeros(*final_t.shape, features.shape[1], dtype=dtype)
        if grad_t is None:
            grad_t = torch.zeros_like(final_t)
        grad_colour, grad_t = _prepare([grad_colour, grad_t], dtype)
        out = [torch.empty_like(t) for t in (means2d, conics, opacities, features)]
        LIBRARY.load()[f"olatbench_backward_{_suffix(dtype)}"](
            pointer(means2d),
            pointer(conics),
            pointer(opacities),
            pointer(features),
            features.shape[1],
            pointer(offsets),
            pointer(ids),
            *_grid(ctx.bins),
            ctx.threads,
            ctx.rules.alpha_max,
            int(ctx.rules.stop_at_t_min),
            pointer(final_t),
            pointer(counts),
            pointer(grad_colour),
            pointer(grad_t),
            n,
            *(pointer(t) for t in out),
        )
        return (*out, None, None, None, None, None)


def rasterize_cpu(
    means2d: torch.Tensor,
    conics: torch.Tensor,
    opacities: torch.Tensor,
    features: torch.Tensor,
    bins: TileBins,
    threads: int | None = None,
    rules: CompositingRules = THREE_DGS,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Composite binned Gaussians on the CPU: colour without background (H, W, C) and final
    transmittance (H, W).

    Same contract (and ``rules``) as ``torch_ref.rasterize_torch``; inputs must be CPU float32 or
    float64 (one dtype). ``threads`` defaults to ``torch.get_num_threads()``. Raises
    ``olatbench._native.BuildError`` if the kernel cannot be built."""
    colour, final_t, _ = _RasterizeCPU.apply(
        means2d,
        conics,
        opacities,
        features,
        bins.offsets,
        bins.gaussian_ids,
        bins,
        thread_count(threads),
        rules,
    )
    return colour, final_t


@torch.no_grad()
def max_weights_cpu(
    means2d: torch.Tensor,
    conics: torch.Tensor,
    opacities: torch.Tensor,
    bins: TileBins,
    threads: int | None = None,
) -> torch.Tensor:
    """``torch_ref.max_weights_torch`` in C++: each Gaussian's largest blending weight ``T·α`` over
    the image (N,), from the forward kernel run without feature channels (its skip and stop
    decisions exactly). CPU float32 or float64 inputs; deterministic whatever ``threads``."""
    dtype, n = means2d.dtype, means2d.shape[0]
    suffix = _suffix(dtype)
    means2d, conics, opacities = _prepare([means2d, conics, opacities], dtype)
    offsets, ids = (
        t.to(device="cpu", dtype=torch.int64).contiguous()
        for t in (bins.offsets, bins.gaussian_ids)
    )
    max_weight = torch.empty(n, dtype=dtype)
    LIBRARY.load()[f"olatbench_max_weight_{suffix}"](
        pointer(means2d),
        pointer(conics),
        pointer(opacities),
        pointer(offsets),
        pointer(ids),
        *_grid(bins),
        thread_count(threads),
        n,
        pointer(max_weight),
    )
    return max_weight


class _ProjectCPU(torch.autograd.Function):
    """``projection.project`` in C++: (means, quats, scales, w2c) -> (means2d, conics, radii,
    depths)."""

    @staticmethod
    def forward(ctx, means, quats, scales, w2c, camera, width, height, threads):
        dtype, n = means.dtype, means.shape[0]
        means, quats, scales = _prepare([means, quats, scales], dtype)
        means2d, conics = torch.empty(n, 2, dtype=dtype), torch.empty(n, 3, dtype=dtype)
        radii, depths = torch.empty(n, dtype=torch.int64), torch.empty(n, dtype=dtype)
        LIBRARY.load()[f"olatbench_project_forward_{_suffix(dtype)}"](
            pointer(means),
            pointer(quats),
            pointer(scales),
            pointer(camera),
            n,
            width,
            height,
            threads,
            pointer(means2d),
            pointer(conics),
            pointer(radii),
            pointer(depths),
        )
        ctx.save_for_backward(means, quats, scales, camera)
        ctx.threads, ctx.w2c_dtype = threads, w2c.dtype
        ctx.mark_non_differentiable(radii)
        return means2d, conics, radii, depths

    @staticmethod
    def backward(ctx, grad_means2d, grad_conics, _grad_radii, grad_depths):
        means, quats, scales, camera = ctx.saved_tensors
        dtype, n = means.dtype, means.shape[0]
        grads = _prepare(
            [
                torch.zeros(n, k, dtype=dtype) if g is None else g.reshape(n, k)
                for g, k in ((grad_means2d, 2), (grad_conics, 3), (grad_depths, 1))
            ],
            dtype,
        )
        out = [torch.empty_like(t) for t in (means, quats, scales)]
        grad_w2c = torch.empty(4, 4, dtype=dtype) if ctx.needs_input_grad[3] else None
        LIBRARY.load()[f"olatbench_project_backward_{_suffix(dtype)}"](
            pointer(means),
            pointer(quats),
            pointer(scales),
            pointer(camera),
            n,
            ctx.threads,
            *(pointer(g) for g in grads),
            *(pointer(t) for t in out),
            pointer(grad_w2c),
        )
        if grad_w2c is not None:
            grad_w2c = grad_w2c.to(ctx.w2c_dtype)
        return (*out, grad_w2c, None, None, None, None)


def project_cpu(
    means: torch.Tensor,
    quats: torch.Tensor,
    scales: torch.Tensor,
    w2c: torch.Tensor,
    K: torch.Tensor,
    width: int,
    height: int,
    near: float,
    far: float,
    low_pass: float,
    threads: int | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """``projection.project`` on CPU float32/float64 tensors: (means2d (N, 2), conics (N, 3), radii
    (N,) int64, depths (N,)), differentiable w.r.t. means, quats, scales and w2c
    (``K`` is a constant)."""
    if means.device.type != "cpu":
        raise ValueError(f"the C++ projection needs CPU tensors, got {means.device}")
    _suffix(means.dtype)
    # Pose and intrinsics rounded to the tensors' precision first, as the torch path uses them.
    pose = w2c.detach().to(dtype=means.dtype).double().reshape(16)
    K = K.detach().to(dtype=means.dtype)
    intrinsics = K.double()
    scalars = [near, far, low_pass, RADIUS_SIGMAS]
    camera = torch.cat(
        [
            pose,
            torch.stack([intrinsics[0, 0], intrinsics[1, 1], intrinsics[0, 2], intrinsics[1, 2]]),
            frustum_clamp_bounds(K, width, height),
            torch.tensor(scalars, dtype=torch.float64),
        ]
    )
    return _ProjectCPU.apply(
        means,
        quats,
        scales,
        w2c,
        camera.contiguous(),
        int(width),
        int(height),
        thread_count(threads),
    )


@torch.no_grad()
def bin_gaussians_cpu(
    means2d: torch.Tensor,
    radii: torch.Tensor,
    sort_keys: torch.Tensor,
    width: int,
    height: int,
    tile_size: int = TILE_SIZE,
) -> TileBins:
    """``tiles.bin_gaussians`` in C++ (identical bins): CPU float32/float64 ``means2d`` (N, 2),
    ``radii`` (N,), ``sort_keys`` (N,) (compared as float32, like the torch version). Serial: one
    radix sort of the N keys, then each Gaussian's tiles filled in that order."""
    if means2d.device.type != "cpu":
        raise ValueError(f"the C++ binning needs CPU tensors, got {means2d.device}")
    lib, dtype = LIBRARY.load(), means2d.dtype
    suffix = _suffix(dtype)
    tiles_x, tiles_y = (width + tile_size - 1) // tile_size, (height + tile_size - 1) // tile_size
    (means2d, keys), n = _prepare([means2d, sort_keys], dtype), means2d.shape[0]
    radii = radii.detach().to(dtype=torch.int64).contiguous()
    grid = (width, height, tile_size, tiles_x, tiles_y)
    if n >= 2**32:
        raise ValueError(f"the C++ binning packs Gaussian indices in 32 bits; got {n} Gaussians")
    offsets = torch.empty(tiles_x * tiles_y + 1, dtype=torch.int64)
    ranges = torch.empty(n, 4, dtype=torch.int64)
    total = lib[f"olatbench_bin_count_{suffix}"](
        pointer(means2d), pointer(radii), n, *grid, pointer(ranges), pointer(offsets)
    )
    ids = torch.empty(total, dtype=torch.int64)
    lib[f"olatbench_bin_fill_{suffix}"](
        pointer(ranges), pointer(keys), n, *grid, pointer(offsets), pointer(ids)
    )
    return TileBins(
        offsets=offsets,
        gaussian_ids=ids,
        tile_size=tile_size,
        tiles_x=tiles_x,
        tiles_y=tiles_y,
        width=int(width),
        height=int(height),
    )


@dataclass
class ShadowGather:
    """Per-Gaussian light-view sums: ``vis_sum`` (N,) Σ ρ·transmittance in front of the Gaussian
    over the pixels within ``radius_px`` of its 2D mean, ``norm`` (N,) Σ ρ over those pixels,
    ``count`` (N,) int32 number of those pixels, ``weight`` (N,) Σ over all pixels of its blending
    weight T·α. ρ = 1 (``norm`` = ``count``) unless ``density``, then ρ = the Gaussian's own 2D
    density exp(-½ dᵀ conic d)."""

    vis_sum: torch.Tensor
    norm: torch.Tensor
    count: torch.Tensor
    weight: torch.Tensor


@torch.no_grad()
def shadow_gather_cpu(
    means2d: torch.Tensor,
    conics: torch.Tensor,
    opacities: torch.Tensor,
    bins: TileBins,
    radius_px: float = 2.0,
    threads: int | None = None,
    *,
    sort_keys: torch.Tensor | None = None,
    depth_offset: float = 0.0,
    density: bool = False,
) -> ShadowGather:
    """Light-view visibility sums (forward only) for Gaussians binned front to back from the light.

    ``means2d`` (N, 2) px, ``conics`` (N, 3), ``opacities`` (N,) as for rendering, projected with
    the light camera; ``bins`` from ``tiles.bin_gaussians(..., sort_keys=<squared distance to the
    light>)``. Each pixel is composited front to back with the 3DGS rules (alpha = min(0.99,
    o·exp(power)), skip alpha < 1/255, stop before T < 1e-4; Gaussians behind a stopped pixel see T
    = 0 there). A pixel whose centre (x+0.5, y+0.5) lies within ``radius_px`` (Euclidean, inclusive)
    of a Gaussian's 2D mean adds the transmittance *in front of* that Gaussian to its ``vis_sum``
    and 1 to its ``count`` and ``norm``; the mean visibility is ``vis_sum / norm`` where
    ``norm > 0``. With ``density`` each such pixel is weighted by ρ, the Gaussian's own 2D density
    exp(-½ dᵀ conic d) (no opacity): ``vis_sum`` = Σ ρ·T and ``norm`` = Σ ρ, summed in float64 and
    rounded once (the official SSD-GS light kernel's ``out_trans`` and ``non_trans``). Only pixels
    in tiles the Gaussian is binned to are seen (always the case for ``radius_px`` ≤ its radius).
    Results are on the CPU in the dtype of ``means2d`` (float32/float64).

    ``depth_offset`` > 0 (sort-key units; needs ``sort_keys`` (N,), the keys ``bins`` was sorted by)
    narrows "in front of g" to the Gaussians j of the tile list with
    ``key_j < key_g - depth_offset``, both sides rounded to float32 as in the tile sort
    (``tiles.float_order_key``; the subtraction is done in float64): Gaussians whose key is within
    the offset of g's do not shadow g. ``weight`` is unaffected. ``depth_offset = 0`` is the plain
    "every Gaussian before g" (``sort_keys`` unused)."""
    dtype = means2d.dtype
    suffix = _suffix(dtype)
    depth_offset = float(depth_offset)
    if not depth_offset >= 0.0:
        raise ValueError(f"depth_offset must be ≥ 0, got {depth_offset}")
    n = means2d.shape[0]
    means2d, conics, opacities = _prepare([means2d, conics, opacities], dtype)
    keys = None
    if depth_offset > 0.0:
        if sort_keys is None or sort_keys.shape != (n,):
            got = "none" if sort_keys is None else f"shape {tuple(sort_keys.shape)}"
            raise ValueError(
                f"depth_offset > 0 needs sort_keys of shape ({n},) (the binning keys), got {got}"
            )
        (keys,) = _prepare([sort_keys], dtype)
    offsets, ids = (
        t.to(device="cpu", dtype=torch.int64).contiguous()
        for t in (bins.offsets, bins.gaussian_ids)
    )
    vis_sum, norm, weight = (torch.empty(n, dtype=dtype) for _ in range(3))
    count = torch.empty(n, dtype=torch.int32)
    LIBRARY.load()[f"olatbench_shadow_gather_{suffix}"](
        pointer(means2d),
        pointer(conics),
        pointer(opacities),
        pointer(keys),
        depth_offset,
        int(density),
        pointer(offsets),
        pointer(ids),
        *_grid(bins),
        radius_px,
        thread_count(threads),
        n,
        pointer(vis_sum),
        pointer(count),
        pointer(norm),
        pointer(weight),
    )
    return ShadowGather(vis_sum=vis_sum, norm=norm, count=count, weight=weight)


__all__ = [
    "LIBRARY",
    "ShadowGather",
    "bin_gaussians_cpu",
    "max_weights_cpu",
    "project_cpu",
    "rasterize_cpu",
    "shadow_gather_cpu",
]
