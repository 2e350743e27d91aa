"""Differentiable rasterization of projected Gaussians with any number of feature channels.

Per pixel, front to back (3DGS rules, `compositing.THREE_DGS`, unless other ``rules`` are given):
``alpha_i = min(0.99, o_i · exp(-½ dᵀ conic_i d))`` with d the offset between the Gaussian's 2D mean
and the pixel centre; Gaussians with ``alpha_i < 1/255`` are skipped and the pixel stops before the
Gaussian that would bring its transmittance below 1e-4. Then

    image = Σ_i T_i α_i f_i + T_final · background,   alpha = 1 - T_final,

and, with ``return_depth``, the expected depth ``Σ_i T_i α_i z_i / alpha`` (0 where alpha < 1e-8),
computed as one more feature channel. Gradients reach means2d, conics, opacities, features and
background (and through ``projection.project`` the 3D parameters and camera pose). Any per-Gaussian
quantity (colour, diffuse, specular, shadow, normals, …) is just a channel of ``features``.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from .backends import resolve_backend
from .compositing import THREE_DGS, CompositingRules
from .projection import Projected
from .tiles import TileBins, bin_gaussians

DEPTH_ALPHA_EPS = 1e-8


@dataclass
class Rasterized:
    """``image`` (H, W, C), ``alpha`` (H, W) = 1 - final transmittance, ``depth`` (H, W) expected
    depth or None, ``backend`` the backend that ran."""

    image: torch.Tensor
    alpha: torch.Tensor
    depth: torch.Tensor | None
    backend: str


def composite(
    means2d: torch.Tensor,
    conics: torch.Tensor,
    opacities: torch.Tensor,
    features: torch.Tensor,
    bins: TileBins,
    backend: str,
    threads: int | None = None,
    rules: CompositingRules = THREE_DGS,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Run one concrete backend: colour without background (H, W, C) and final transmittance (H, W).
    The cuda backend is gsplat's kernel, whose rules are its own (`compositing.GSPLAT`) whatever
    ``rules`` says."""
    if backend == "torch":
        from .backends.torch_ref import rasterize_torch

        return rasterize_torch(means2d, conics, opacities, features, bins, rules)
    if backend == "cpu":
        from .backends.cpu import rasterize_cpu

        return rasterize_cpu(
            means2d, conics, opacities, features, bins, threads=threads, rules=rules
        )
    if backend == "cuda":
        from .backends.cuda import rasterize_cuda

        return rasterize_cuda(means2d, conics, opacities, features, bins)
    raise ValueError(f"unknown concrete backend {backend!r}")


def backend_and_bins(
    projected: Projected, backend: str, bins: TileBins | None
) -> tuple[str, TileBins]:
    """The compositing backend resolved for ``projected`` and its tile bins (``bins``, or made by
    the C++ binning when that backend is "cpu" and by torch otherwise)."""
    name = resolve_backend(backend, projected.means2d.device, projected.means2d.dtype)
    if bins is None:
        bins = bin_gaussians(
            projected.means2d,
            projected.radii,
            projected.depths,
            projected.width,
            projected.height,
            backend="cpu" if name == "cpu" else "torch",
        )
    return name, bins


def rasterize(
    projected: Projected,
    opacities: torch.Tensor,
    features: torch.Tensor,
    background: torch.Tensor,
    backend: str = "auto",
    return_depth: bool = False,
    threads: int | None = None,
    bins: TileBins | None = None,
    rules: CompositingRules = THREE_DGS,
) -> Rasterized:
    """Composite ``projected`` Gaussians with ``opacities`` (N,) in [0, 1] and ``features`` (N, C)
    over ``background`` (C,). ``backend``: "auto", "torch", "cpu" or "cuda"
    (see ``olatbench.gaussians.backends``). ``threads`` applies to the cpu backend
    (default ``torch.get_num_threads()``). ``bins`` may be passed to reuse a binning (it must come
    from ``bin_gaussians`` on these means2d/radii, sorted by depth). ``rules``: the alpha clamp and
    stopping rule (`olatbench.gaussians.compositing`; the torch and cpu backends)."""
    n = projected.means2d.shape[0]
    if features.ndim != 2 or features.shape[0] != n:
        raise ValueError(f"features must be (N={n}, C), got {tuple(features.shape)}")
    if opacities.shape != (n,):
        raise ValueError(f"opacities must be (N={n},), got {tuple(opacities.shape)}")
    channels = features.shape[1]
    background = torch.as_tensor(background, dtype=features.dtype, device=features.device)
    if background.shape != (channels,):
        raise ValueError(f"background must be (C={channels},), got {tuple(background.shape)}")
    dtype = projected.means2d.dtype
    name, bins = backend_and_bins(projected, backend, bins)
    feats = features.to(dtype)
    if return_depth:
        feats = torch.cat([feats, projected.depths.to(dtype)[:, None]], dim=1)
    colour, final_t = composite(
        projected.means2d,
        projected.conics,
        opacities.to(dtype),
        feats,
        bins,
        name,
        threads=threads,
        rules=rules,
    )
    alpha = 1.0 - final_t
    image = colour[..., :channels] + final_t[..., None] * background.to(dtype)
    depth = None
    if return_depth:
        covered = alpha > DEPTH_ALPHA_EPS
        depth = torch.where(
            covered,
            colour[..., channels] / torch.where(covered, alpha, torch.ones_like(alpha)),
            0.0,
        )
    return Rasterized(image=image, alpha=alpha, depth=depth, backend=name)


__all__ = ["Rasterized", "composite", "rasterize"]
