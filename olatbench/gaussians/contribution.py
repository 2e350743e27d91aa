"""Contribution culling: each Gaussian's largest blending weight over a view, to shade only what
reaches a pixel.

Gaussian i enters pixel p of the camera pass as ``w_ip · f_i`` with ``w_ip = T_ip · α_ip`` its
blending weight (`olatbench.gaussians.rasterize`). `max_weights` is a cheap first pass, the camera
pass's compositing with no feature channels, that returns ``m_i = max_p w_ip`` (0 where i is
composited nowhere: skipped as too faint, behind pixels that already stopped, or off the image). A
method that gives every Gaussian with ``m_i ≤ ε`` zero features instead of its shaded colour changes
each pixel by at most ``ε · Σ |f_i|`` over those Gaussians; with ε = 0 it drops exactly the
Gaussians whose features the compositing never reads, so the image and every gradient stay what they
were. Their geometry is still composited (they may occlude), so it keeps its gradients through the
alpha blending.

Backends as the rasterizer's: ``cpu`` runs the C++ forward kernel
(``backends.cpu.max_weights_cpu``), the others the torch reference
(``backends.torch_ref.max_weights_torch``); both apply the same skip and stop rules.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from .projection import Projected
from .rasterize import backend_and_bins
from .tiles import TileBins


@dataclass
class Contribution:
    """``max_weight`` (N,) each Gaussian's largest blending weight in the view, ``bins`` the view's
    tile binning (pass it on to `rasterize` to bin once) and ``backend`` the backend that ran."""

    max_weight: torch.Tensor
    bins: TileBins
    backend: str


@torch.no_grad()
def max_weights(
    projected: Projected,
    opacities: torch.Tensor,
    backend: str = "auto",
    threads: int | None = None,
    bins: TileBins | None = None,
) -> Contribution:
    """Largest blending weight of each of the N ``projected`` Gaussians with ``opacities`` (N,) over
    the view's pixels. ``backend``, ``threads`` and ``bins`` as for `rasterize`; no gradient flows
    through the result."""
    n = projected.means2d.shape[0]
    if opacities.shape != (n,):
        raise ValueError(f"opacities must be (N={n},), got {tuple(opacities.shape)}")
    dtype = projected.means2d.dtype
    name, bins = backend_and_bins(projected, backend, bins)
    args = (
        projected.means2d.detach(),
        projected.conics.detach(),
        opacities.detach().to(dtype),
        bins,
    )
    if name == "cpu":
        from .backends.cpu import max_weights_cpu

        weights = max_weights_cpu(*args, threads=threads)
    else:
        from .backends.torch_ref import max_weights_torch

        weights = max_weights_torch(*args)
    return Contribution(max_weight=weights, bins=bins, backend=name)


__all__ = ["Contribution", "max_weights"]
