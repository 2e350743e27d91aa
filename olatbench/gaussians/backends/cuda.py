"""CUDA backend: gsplat's ``rasterize_to_pixels`` fed with olatbench's own projection and tile bins.

Called as ``gsplat.rasterize_to_pixels(means2d [1,N,2], conics [1,N,3], colors [1,N,C], opacities
[1,N], image_width, image_height, tile_size, isect_offsets [1,th,tw] int32, flatten_ids [M] int32)
-> (colours [1,H,W,C], alphas [1,H,W,1])`` with one camera. Conventions, each checked against
gsplat's own torch references on CPU tensors in ``tests/test_gsplat_conventions.py``
(no GPU has run this module):

- **pixel centres** at ``(x + 0.5, y + 0.5)`` in both, and ``means2d = K (x/z, y/z, 1)`` with ``K``
  in that convention (gsplat's ``_fully_fused_projection`` gives olatbench's means2d to float64
  rounding);
- **conics** ``(a, b, c)`` of the inverse 2D covariance ``[[a, b], [b, c]]`` and ``sigma = ½(a dx² +
  c dy²) + b dx dy`` in both (gsplat's conics equal olatbench's, same 0.3 px low-pass and 1.3×
  frustum clamp);
- **tile bins**: gsplat's ``isect_offsets`` are the tile *starts* in row-major tile order, shaped
  (th, tw), so they are ``bins.offsets[:-1]`` reshaped; ``flatten_ids``
  (ids in [0, N) for one camera) are ``bins.gaussian_ids``, front to back per tile. gsplat's own
  binning (not used here) takes tiles [floor((m-r)/16), ceil((m+r)/16)) with per-axis radii
  ``ceil(3.33·sqrt(Σ_xx))``, a superset of olatbench's (pixel centres within the 3σ box of λ_max);
- **transmittance**: both skip ``sigma < 0`` and ``alpha < 1/255`` and stop before the Gaussian that
  takes T to 1e-4; gsplat clamps ``alpha`` at ``GSPLAT_ALPHA_MAX = 0.999`` where 3DGS and the
  cpu/torch backends clamp at 0.99, so a pixel behind one opaque Gaussian keeps T = 0.001 here and
  0.01 there (elsewhere the results agree to rounding); ``1 - alphas`` is the final transmittance;
- **gradients**: gsplat's hand-written CUDA backward; its torch twin's autograd gradients equal
  olatbench's reference (float64) once the clamp is the same.

gsplat's kernels are float32 only: the methods train in float32 on CUDA.
"""

from __future__ import annotations

import functools
import importlib.util

import torch

from ..compositing import GSPLAT
from ..screen import TileBins

# gsplat's kernels clamp alpha at 0.999 (olatbench's torch and C++ backends at 3DGS's 0.99 by
# default).
GSPLAT_ALPHA_MAX = GSPLAT.alpha_max


def gsplat_version() -> str | None:
    """The installed gsplat's version, or None when it is not installed (imports nothing)."""
    if importlib.util.find_spec("gsplat") is None:
        return None
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("gsplat")
    except PackageNotFoundError:
        return "unknown version"


@functools.cache
def gsplat_status() -> tuple[bool, str]:
    """(usable, detail) of the CUDA backend, checked once per process.

    Usable when gsplat is installed, a CUDA device is present and gsplat's CUDA extension loads.
    Loading it is attempted only when CUDA is present; gsplat compiles it with the CUDA toolkit on
    first use (minutes, cached in torch's extension folder) and, without a toolkit, leaves it unset
    after printing a warning."""
    found = gsplat_version()
    if found is None:
        return False, "gsplat not installed (pip install 'olatbench[cuda]')"
    if not torch.cuda.is_available():
        return False, f"gsplat {found}; no CUDA device, so its extension was not compiled"
    try:
        from gsplat.cuda._backend import _C
    except Exception as error:  # a failed JIT build raises from inside torch.utils.cpp_extension
        return (
            False,
            f"gsplat {found}; its CUDA extension failed to build: {type(error).__name__}: {error}",
        )
    if _C is None:
        return (
            False,
            f"gsplat {found}; its CUDA extension is unavailable (no CUDA toolkit found: install "
            "nvcc)",
        )
    return True, f"gsplat {found}; CUDA extension loaded"


def gsplat_available() -> bool:
    """True when the CUDA backend can run: gsplat installed, a CUDA device present, its extension
    loaded."""
    return gsplat_status()[0]


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


__all__ = [
    "GSPLAT_ALPHA_MAX",
    "gsplat_available",
    "gsplat_status",
    "gsplat_version",
    "rasterize_cuda",
]
