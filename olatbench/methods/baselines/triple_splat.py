"""GS³'s screen-space composite ("triple splatting" in image space): ``I_px · V_px + O_px``.

Per Gaussian, GS³ computes a shaded colour I (Lambert + specular, with the cosine and ``I/d²``), a
shadow factor V and an "other effects" colour O. They are splatted as separate channels of *one*
rasterization, each alpha-blended on its own::

    I_px = Σ_i T_i α_i I_i + T · b,    V_px = Σ_i T_i α_i V_i + T · b_V,    O_px = Σ_i T_i α_i O_i

(T_i the transmittance before Gaussian i, T the final one, b the background colour), and only then
combined per pixel as ``I_px · V_px + O_px``. Shadowing therefore happens *after* projection, in
screen space, unlike SSD-GS, which multiplies each Gaussian's colour by its own shadow before
blending (the difference the paper's appendix on screen-space shadow baselines is about). The
official code blends V over a background of 1 on white backgrounds and 0 on black ones; ``b_V = 1``
whenever the background is not black reproduces both and keeps an empty pixel at the background
colour.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from olatbench.gaussians.projection import Projected
from olatbench.gaussians.rasterize import rasterize
from olatbench.gaussians.tiles import TileBins


@dataclass
class TripleSplat:
    """Screen-space channels (H, W, ·): ``shading`` I_px (3), ``visibility`` V_px (1), ``other``
    O_px (3), the composite ``image`` (3), any ``extras`` (C) splatted alongside (zero background),
    and the coverage ``alpha``
    (1) = 1 - the final transmittance T."""

    shading: torch.Tensor
    visibility: torch.Tensor
    other: torch.Tensor
    image: torch.Tensor
    extras: torch.Tensor | None
    alpha: torch.Tensor


def visibility_background(background: torch.Tensor) -> torch.Tensor:
    """``b_V`` (1,): 1 unless the background is black (see the module docstring)."""
    return (background.abs().amax() > 0).to(background.dtype).reshape(1)


def composite(shading: torch.Tensor, visibility: torch.Tensor, other: torch.Tensor) -> torch.Tensor:
    """The per-pixel GS³ composite ``I · V + O`` of screen-space channels (…, 3), (…, 1), (…, 3)."""
    return shading * visibility + other


def triple_splat(
    projected: Projected,
    opacities: torch.Tensor,
    shading: torch.Tensor,
    visibility: torch.Tensor,
    other: torch.Tensor,
    background: torch.Tensor,
    extras: torch.Tensor | None = None,
    backend: str = "auto",
    bins: TileBins | None = None,
) -> TripleSplat:
    """Splat per-Gaussian ``shading`` (N,3), ``visibility`` (N,1), ``other`` (N,3)
    (and ``extras`` (N,C)) in one rasterize call over ``background`` (3,) and composite them per
    pixel; ``bins`` as for `rasterize`."""
    parts = [shading, visibility, other] + ([extras] if extras is not None else [])
    features = torch.cat(parts, dim=1)
    extra_channels = 0 if extras is None else extras.shape[1]
    full_background = torch.cat(
        [background, visibility_background(background), background.new_zeros(3 + extra_channels)]
    )
    splatted = rasterize(
        projected, opacities, features, full_background, backend=backend, bins=bins
    )
    image = splatted.image
    shading_px, visibility_px, other_px = image[..., 0:3], image[..., 3:4], image[..., 4:7]
    return TripleSplat(
        shading=shading_px,
        visibility=visibility_px,
        other=other_px,
        image=composite(shading_px, visibility_px, other_px),
        extras=image[..., 7:] if extras is not None else None,
        alpha=splatted.alpha[..., None],
    )


__all__ = ["TripleSplat", "composite", "triple_splat", "visibility_background"]
