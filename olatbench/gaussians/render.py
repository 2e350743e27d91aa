"""One-call rendering: project 3D Gaussians with a camera, then rasterize them."""

from __future__ import annotations

import torch

from .projection import project
from .rasterize import rasterize


def render(
    means: torch.Tensor,
    quats: torch.Tensor,
    scales: torch.Tensor,
    opacities: torch.Tensor,
    features: torch.Tensor,
    w2c: torch.Tensor,
    K: torch.Tensor,
    width: int,
    height: int,
    background: torch.Tensor,
    backend: str = "auto",
    return_depth: bool = False,
    near: float = 0.01,
    far: float = 1e10,
    threads: int | None = None,
) -> dict[str, torch.Tensor | None]:
    """Render Gaussians (means (N,3), quats (N,4) wxyz, linear scales (N,3), opacities (N,),
    features (N,C)) seen by ``w2c`` (4,4, OpenCV axes) and ``K`` (3,3, pixel centres at +0.5) over
    ``background`` (C,).

    Returns ``image`` (H,W,C), ``alpha`` (H,W), ``depth`` (H,W) or None, ``means2d`` (N,2)
    (non-leaf: call ``.retain_grad()`` on it before backward to get the screen-space gradient used
    by densification), ``radii`` (N,) int and ``visible`` (N,) bool (radius > 0).
    ``backend="torch"`` also projects in torch (the reference end to end); otherwise the projection
    takes its "auto" choice."""
    projected = project(
        means,
        quats,
        scales,
        w2c,
        K,
        width,
        height,
        near=near,
        far=far,
        backend="torch" if backend == "torch" else "auto",
    )
    out = rasterize(
        projected,
        opacities,
        features,
        background,
        backend=backend,
        return_depth=return_depth,
        threads=threads,
    )
    return {
        "image": out.image,
        "alpha": out.alpha,
        "depth": out.depth,
        "means2d": projected.means2d,
        "radii": projected.radii,
        "visible": projected.radii > 0,
    }


__all__ = ["render"]
