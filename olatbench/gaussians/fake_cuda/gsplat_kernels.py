"""Shape-level stand-ins of the two compiled gsplat kernels the camera pass calls, for fake CUDA
tensors.

``olatbench.gaussians.backends.cuda.rasterize_cuda`` calls ``gsplat.rasterize_to_pixels``
(gsplat 1.5.3, ``gsplat/cuda/_wrapper.py``), whose Python runs unchanged under fake tensors (its
shape asserts, the channel padding, ``_RasterizeToPixels``' autograd ``forward``/``backward``) until
it calls the compiled kernels through ``_make_lazy_cuda_func("rasterize_to_pixels_3dgs_fwd" /
"..._bwd")``. Those cannot run on fake tensors, so `install` replaces ``_make_lazy_cuda_func`` for
these two names by ports of their host-side bindings (``gsplat/cuda/csrc/Rasterization.cpp``: the
``CHECK_INPUT`` of every tensor, CUDA and contiguous, and the outputs allocated with ``means2d``'s
options) plus the dtypes the kernels read through ``data_ptr<T>()`` (``RasterizeToPixels3DGSFwd.cu``
/ ``...Bwd.cu``: float32 Gaussians, colours and gradients, int32 tile offsets and ids, bool masks),
and their device (one CUDA device for all). The values are not computed: the outputs are fake. Any
other compiled gsplat function raises, naming itself.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import torch

F32, I32 = torch.float32, torch.int32


def _check(
    tensor: torch.Tensor | None, name: str, dtype: torch.dtype, device: torch.device
) -> None:
    """gsplat's CHECK_INPUT (Common.h: CUDA, contiguous) plus the dtype its kernel reads and the
    launch device."""
    if tensor is None:
        return
    if tensor.device.type != "cuda":
        raise RuntimeError(
            f"{name} must be a CUDA tensor (gsplat Rasterization.cpp CHECK_INPUT), got "
            f"{tensor.device}"
        )
    if not tensor.is_contiguous():
        raise RuntimeError(f"{name} must be contiguous (gsplat Rasterization.cpp CHECK_INPUT)")
    if tensor.dtype != dtype:
        raise RuntimeError(
            f"{name} must be {dtype} (gsplat's kernel reads data_ptr of that type), got "
            f"{tensor.dtype}"
        )
    if tensor.device != device:
        raise RuntimeError(
            f"{name} is on {tensor.device}, the kernel launches on {device} (means2d's device)"
        )


def _check_inputs(
    means2d, conics, colors, opacities, backgrounds, masks, tile_offsets, flatten_ids
) -> None:
    device = means2d.device
    for tensor, name, dtype in (
        (means2d, "means2d", F32),
        (conics, "conics", F32),
        (colors, "colors", F32),
        (opacities, "opacities", F32),
        (backgrounds, "backgrounds", F32),
        (masks, "masks", torch.bool),
        (tile_offsets, "tile_offsets", I32),
        (flatten_ids, "flatten_ids", I32),
    ):
        _check(tensor, name, dtype, device)


def rasterize_to_pixels_3dgs_fwd(
    means2d,
    conics,
    colors,
    opacities,
    backgrounds,
    masks,
    image_width: int,
    image_height: int,
    tile_size: int,
    tile_offsets,
    flatten_ids,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Rasterization.cpp:20-115: renders [..., H, W, C], alphas [..., H, W, 1] (means2d's options),
    last_ids [..., H, W] int32."""
    _check_inputs(means2d, conics, colors, opacities, backgrounds, masks, tile_offsets, flatten_ids)
    image_dims = tuple(tile_offsets.shape[:-2])
    channels = colors.shape[-1]
    options = dict(dtype=means2d.dtype, device=means2d.device)
    renders = torch.empty(*image_dims, image_height, image_width, channels, **options)
    alphas = torch.empty(*image_dims, image_height, image_width, 1, **options)
    last_ids = torch.empty(*image_dims, image_height, image_width, dtype=I32, device=means2d.device)
    return renders, alphas, last_ids


def rasterize_to_pixels_3dgs_bwd(
    means2d,
    conics,
    colors,
    opacities,
    backgrounds,
    masks,
    image_width: int,
    image_height: int,
    tile_size: int,
    tile_offsets,
    flatten_ids,
    render_alphas,
    last_ids,
    v_render_colors,
    v_render_alphas,
    absgrad: bool,
) -> tuple[torch.Tensor | None, ...]:
    """Rasterization.cpp:117-228: (v_means2d_abs or None, v_means2d, v_conics, v_colors,
    v_opacities), each zeros_like its input."""
    _check_inputs(means2d, conics, colors, opacities, backgrounds, masks, tile_offsets, flatten_ids)
    for tensor, name, dtype in (
        (render_alphas, "render_alphas", F32),
        (last_ids, "last_ids", I32),
        (v_render_colors, "v_render_colors", F32),
        (v_render_alphas, "v_render_alphas", F32),
    ):
        _check(tensor, name, dtype, means2d.device)
    v_abs = torch.zeros_like(means2d) if absgrad else None
    return (
        v_abs,
        torch.zeros_like(means2d),
        torch.zeros_like(conics),
        torch.zeros_like(colors),
        torch.zeros_like(opacities),
    )


KERNELS: dict[str, Callable[..., Any]] = {
    "rasterize_to_pixels_3dgs_fwd": rasterize_to_pixels_3dgs_fwd,
    "rasterize_to_pixels_3dgs_bwd": rasterize_to_pixels_3dgs_bwd,
}


def _lazy_kernel(name: str) -> Callable[..., Any]:
    def kernel(*args: Any, **kwargs: Any) -> Any:
        if name not in KERNELS:
            raise NotImplementedError(
                f"the fake-CUDA dry run has no stand-in for gsplat's compiled {name!r}"
            )
        return KERNELS[name](*args, **kwargs)

    return kernel


@contextmanager
def install() -> Iterator[None]:
    """Point gsplat's ``_make_lazy_cuda_func`` at `KERNELS` for the duration
    (gsplat must be installed)."""
    from gsplat.cuda import _wrapper

    original = _wrapper._make_lazy_cuda_func
    _wrapper._make_lazy_cuda_func = _lazy_kernel
    try:
        yield
    finally:
        _wrapper._make_lazy_cuda_func = original


__all__ = ["KERNELS", "install", "rasterize_to_pixels_3dgs_bwd", "rasterize_to_pixels_3dgs_fwd"]
