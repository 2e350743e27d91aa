"""``gsplat.rasterization`` as gsplat v1.1.1 defines it, on the CPU: gsplat's projection,
olatbench's rasterizer.

The authors' SSD-GS and GS³ call (``gaussian_renderer/__init__.py``)::

    rendered, alphas, meta = rasterization(means, quats, scales, opacities, colors [N, D],
        viewmats [1, 4, 4], Ks [1, 3, 3], width, height, near_plane, far_plane, eps2d=0.3,
        sh_degree=None, packed=False, backgrounds [1, D])

and read ``meta["radii"]`` ([C, N] in 1.1.1) and ``meta["means2d"]`` ([C, N, 2], on which they call
``retain_grad()`` to read the screen-space gradient for densification). This function has 1.1.1's
signature and return values for that use: any channel count D, per-camera backgrounds, ``eps2d``
(the 2D low-pass), ``near_plane``/``far_plane`` and ``radius_clip`` culling; ``render_colors``
[C, H, W, D], ``render_alphas`` [C, H, W, 1]. ``meta["means2d"]`` is the tensor the rasterizer
consumes, so after ``backward`` its ``.grad`` is the gradient of the loss with respect to the 2D
means in pixels, as gsplat's.

Options whose behaviour is not reproduced raise `NotImplementedError` naming the option:
``packed=True`` (its meta has other shapes), ``sh_degree`` (colours must be precomputed),
``render_mode`` other than "RGB", ``rasterize_mode="antialiased"``, ``absgrad``, ``sparse_grad``,
``distributed``.

The projection is gsplat 1.1.1's (`projection.project_gsplat`: its symmetric Jacobian clamp, radius
floor and near-plane rule, not olatbench's 3DGS ones), so are the tile lists
(`projection.gsplat_bins`), and the C++ rasterizer composites them with gsplat's rules
(`olatbench.gaussians.compositing.GSPLAT`: alpha clamped at 0.999, a pixel stops before the Gaussian
that takes its transmittance to 1e-4 or below). tests/test_cpu_standins.py checks each against
gsplat 1.1.1's formulas and gsplat's own torch code. What remains different is the arithmetic: the
CUDA kernels' float32 ``__expf`` and fused operations against the C++ kernel's.
"""

from __future__ import annotations

from typing import Any

import torch

from olatbench.gaussians.compositing import GSPLAT
from olatbench.gaussians.projection import Projected
from olatbench.gaussians.rasterize import rasterize

from .projection import gsplat_bins, project_gsplat

TILE_SIZE = 16


def _refuse(name: str, value: Any, supported: Any) -> None:
    if value != supported:
        raise NotImplementedError(
            f"gsplat stand-in (olatbench CPU): rasterization({name}={value!r}) is not "
            f"implemented; only {name}={supported!r}, as the authors' code calls it"
        )


def rasterization(
    means: torch.Tensor,
    quats: torch.Tensor,
    scales: torch.Tensor,
    opacities: torch.Tensor,
    colors: torch.Tensor,
    viewmats: torch.Tensor,
    Ks: torch.Tensor,
    width: int,
    height: int,
    near_plane: float = 0.01,
    far_plane: float = 1e10,
    radius_clip: float = 0.0,
    eps2d: float = 0.3,
    sh_degree: int | None = None,
    packed: bool = True,
    tile_size: int = TILE_SIZE,
    backgrounds: torch.Tensor | None = None,
    render_mode: str = "RGB",
    sparse_grad: bool = False,
    absgrad: bool = False,
    rasterize_mode: str = "classic",
    channel_chunk: int = 32,
    distributed: bool = False,
) -> tuple[torch.Tensor, torch.Tensor, dict[str, Any]]:
    """gsplat 1.1.1 ``rasterization`` (module docstring). ``means`` [N, 3], ``quats`` [N, 4] wxyz,
    ``scales`` [N, 3] linear, ``opacities`` [N], ``colors`` [N, D] or [C, N, D], ``viewmats``
    [C, 4, 4] world-to-camera (OpenCV axes), ``Ks`` [C, 3, 3] (pixel centres at +0.5),
    ``backgrounds`` [C, D] or None (black)."""
    del channel_chunk  # a memory knob of the CUDA kernels: the result does not depend on it
    for name, value, supported in (
        ("packed", packed, False),
        ("sh_degree", sh_degree, None),
        ("render_mode", render_mode, "RGB"),
        ("rasterize_mode", rasterize_mode, "classic"),
        ("absgrad", absgrad, False),
        ("sparse_grad", sparse_grad, False),
        ("distributed", distributed, False),
        ("tile_size", tile_size, TILE_SIZE),
    ):
        _refuse(name, value, supported)
    n, cameras = means.shape[0], viewmats.shape[0]
    if colors.ndim == 2:
        colors = colors[None].expand(cameras, -1, -1)
    if colors.shape[:2] != (cameras, n):
        raise ValueError(
            f"gsplat stand-in: colors must be [N={n}, D] or [C={cameras}, N, D], got "
            f"{tuple(colors.shape)}"
        )
    channels = colors.shape[-1]
    if backgrounds is None:
        backgrounds = colors.new_zeros(cameras, channels)
    if backgrounds.shape != (cameras, channels):
        raise ValueError(
            f"gsplat stand-in: backgrounds must be [C={cameras}, D={channels}], got "
            f"{tuple(backgrounds.shape)}"
        )
    projected = [
        project_gsplat(
            means,
            quats,
            scales,
            viewmats[c],
            Ks[c],
            int(width),
            int(height),
            near_plane,
            far_plane,
            eps2d,
            radius_clip,
        )
        for c in range(cameras)
    ]
    # [C, N, 2]: the tensor the rasterizer reads
    means2d = torch.stack([p.means2d for p in projected])
    radii = torch.stack([p.radii for p in projected])
    images, alphas = [], []
    for c, p in enumerate(projected):
        camera = Projected(
            means2d=means2d[c],
            conics=p.conics,
            radii=p.radii,
            depths=p.depths,
            width=p.width,
            height=p.height,
        )
        out = rasterize(
            camera, opacities, colors[c], backgrounds[c], rules=GSPLAT, bins=gsplat_bins(camera)
        )
        images.append(out.image)
        alphas.append(out.alpha[..., None])
    meta = {
        "radii": radii.to(torch.int32),
        "means2d": means2d,
        "depths": torch.stack([p.depths for p in projected]),
        "conics": torch.stack([p.conics for p in projected]),
        "opacities": opacities[None].expand(cameras, -1),
        "width": int(width),
        "height": int(height),
        "tile_size": tile_size,
        "n_cameras": cameras,
        "camera_ids": None,
        "gaussian_ids": None,
    }
    return torch.stack(images), torch.stack(alphas), meta
