"""The front-to-back compositing rules a rasterizer follows (which clamp, which stop).

Per pixel, Gaussians front to back: ``alpha = min(alpha_max, o·exp(power))``; pairs with
``power > 0`` or ``alpha < 1/255`` are skipped; the pixel stops, without the Gaussian, at the first
one whose next transmittance is below 1e-4 (3DGS, `THREE_DGS`) or at or below it (``stop_at_t_min``;
gsplat's ``next_T <= 1e-4``, `GSPLAT`). olatbench's own methods composite with `THREE_DGS`; the CPU
stand-in of ``gsplat.rasterization`` for the authors' SSD-GS and GS³ code
(``methods.official.cpu_standins``) with `GSPLAT` (gsplat 1.1.1's
``rasterize_to_pixels_fwd.cu:134,140``; its backward ``rasterize_to_pixels_bwd.cu:163,207`` passes
gradients where ``o·exp(power) <= 0.999``).
"""

from __future__ import annotations

from dataclasses import dataclass

ALPHA_MIN = 1.0 / 255.0  # pairs below it are skipped (both rules)
T_MIN = 1e-4  # the transmittance at which a pixel stops (both rules; strictly below or at-or-below)


@dataclass(frozen=True)
class CompositingRules:
    """``alpha_max``: the clamp on a pair's alpha; ``stop_at_t_min``: a pixel stops before the
    Gaussian whose next transmittance is <= `T_MIN` (True) or < `T_MIN` (False)."""

    alpha_max: float
    stop_at_t_min: bool


THREE_DGS = CompositingRules(alpha_max=0.99, stop_at_t_min=False)
GSPLAT = CompositingRules(alpha_max=0.999, stop_at_t_min=True)

__all__ = ["ALPHA_MIN", "GSPLAT", "THREE_DGS", "T_MIN", "CompositingRules"]
