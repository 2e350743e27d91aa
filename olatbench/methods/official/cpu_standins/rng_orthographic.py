"""``diff_gaussian_rasterization_orthographic``, RNG's orthographic variant (sssssy/RNG_release @
4e8748e, ``submodules/diff-gaussian-rasterization-orthographic``), on the CPU.

RNG builds it for the shadow map of a directional light, which
``gaussian_renderer/__init__.py:276-303`` renders only when ``render(..., relight_envmap=...)`` is
given; ``train.py`` never gives it and ``render.py`` raises ``NotImplementedError`` before
(``render.py:36-37, 68-69``), so RNG's commands import this module
(``gaussian_renderer/__init__.py:16``) without calling it. It is reproduced for that import and
checked on its own.

Its forward differs from RNG's perspective fork (`rng_rasterizer`) in ``cuda_rasterizer/forward.cu``
of that folder: no near culling (``in_frustum`` removed, forward.cu:216); a Gaussian's depth is
``(mean - cam_center) · light_dir`` and its image position ``((p·cam_right) + 1) / 2 · (W - 1) +
0.5`` (and ``cam_up`` for y) with ``p = (mean - cam_center) - depth · light_dir``, clamped at ``W -
0.5`` (forward.cu:80-86, 255-258, in Inria's integer pixel centres); the 2D covariance is
``J W Σ Wᵀ Jᵀ + 0.3 I`` with ``W`` the rows (cam_right, cam_up, normalize(light_dir)) and
``J = diag(W / 2, H / 2)`` (forward.cu:103-135; the settings' low-pass radius is ignored); radii,
culling and compositing are Inria's, and the outputs are the fork's (color, radii, depth, alpha).

Its backward cannot run: ``backward.cu`` is the perspective one, and the Python backward reads
``raster_settings.tanfovx`` (``__init__.py:122-123``), which its settings do not have
(``GaussianRasterizationSettings``, ``__init__.py:160-177``), so any gradient through it raises
AttributeError. ``--shadow_grad`` therefore lets no gradient through this path; here ``backward``
raises the same AttributeError.
"""

from __future__ import annotations

from typing import NamedTuple

import torch
from torch import nn

from olatbench.gaussians.projection import Projected, covariances_3d
from olatbench.gaussians.rasterize import rasterize
from olatbench.methods.official.cpu_standins.rng_rasterizer import (
    NUM_CHANNELS,
    _refuse,
    inria_bins,
    inria_radii,
)

LOW_PASS = 0.3  # forward.cu:133-134, fixed
IMAGE_PLANE_SIZE = 2.0  # forward.cu:236: the plane spans [-1, 1] along cam_right and cam_up


class GaussianRasterizationSettings(NamedTuple):
    """The orthographic settings
    (``diff_gaussian_rasterization_orthographic/__init__.py:160-177``)."""

    image_height: int
    image_width: int
    light_dir: torch.Tensor
    cam_center: torch.Tensor
    cam_right: torch.Tensor
    cam_up: torch.Tensor
    bg: torch.Tensor
    scale_modifier: float
    viewmatrix: torch.Tensor
    projmatrix: torch.Tensor
    sh_degree: int
    campos: torch.Tensor
    prefiltered: bool
    debug: bool
    low_pass_filter_radius: float


class _NoBackward(torch.autograd.Function):
    """Identity whose backward fails as the fork's does (module docstring)."""

    @staticmethod
    def forward(ctx, *tensors: torch.Tensor) -> tuple[torch.Tensor, ...]:
        return tuple(t.clone() for t in tensors)

    @staticmethod
    def backward(ctx, *grads: torch.Tensor):
        raise AttributeError(
            "'GaussianRasterizationSettings' object has no attribute 'tanfovx' (RNG's orthographic "
            "rasterizer has no backward: diff_gaussian_rasterization_orthographic/__init__.py:122)"
        )


def project_orthographic(
    means: torch.Tensor,
    quats: torch.Tensor,
    scales: torch.Tensor,
    settings: GaussianRasterizationSettings,
) -> tuple[Projected, torch.Tensor]:
    """(the projected Gaussians in olatbench's pixel convention, their radii by Inria's rule)
    (module docstring)."""
    width, height = int(settings.image_width), int(settings.image_height)
    dtype = means.dtype
    light, centre, right, up = (
        getattr(settings, name).to(dtype).reshape(3)
        for name in ("light_dir", "cam_center", "cam_right", "cam_up")
    )
    offset = means - centre
    depth = offset @ light
    in_plane = offset - depth[:, None] * light
    half = IMAGE_PLANE_SIZE / 2
    px, py = (in_plane @ right) / half, (in_plane @ up) / half
    x = torch.clamp((px + half) / IMAGE_PLANE_SIZE * (width - 1) + 0.5, max=width - 1 + 0.5) + 0.5
    y = torch.clamp((py + half) / IMAGE_PLANE_SIZE * (height - 1) + 0.5, max=height - 1 + 0.5) + 0.5
    rows = torch.stack([right, up, light / light.norm()])  # W: world -> (right, up, forward)
    jacobian = torch.diag(
        torch.tensor([width / IMAGE_PLANE_SIZE, height / IMAGE_PLANE_SIZE], dtype=dtype)
    )
    cov = jacobian @ rows[:2] @ covariances_3d(quats, scales) @ rows[:2].T @ jacobian.T
    a, b, c = cov[:, 0, 0] + LOW_PASS, cov[:, 0, 1], cov[:, 1, 1] + LOW_PASS
    det = a * c - b * b
    safe = torch.where(det != 0, det, torch.ones_like(det))
    conics = torch.stack([c / safe, -b / safe, a / safe], dim=-1)
    means2d = torch.stack([x, y], dim=-1)
    radii = inria_radii(means2d, conics, det != 0, width, height)
    return Projected(
        means2d=means2d, conics=conics, radii=radii, depths=depth, width=width, height=height
    ), radii


class GaussianRasterizer(nn.Module):
    """The orthographic ``GaussianRasterizer``: returns (color [16, H, W], radii [N], depth
    [1, H, W], alpha [1, H, W]) as RNG's perspective fork does (depth = Σ z α T, alpha = Σ α T)."""

    def __init__(self, raster_settings: GaussianRasterizationSettings) -> None:
        super().__init__()
        self.raster_settings = raster_settings

    def forward(
        self,
        means3D,
        means2D,
        opacities,
        shs=None,
        colors_precomp=None,
        scales=None,
        rotations=None,
        cov3D_precomp=None,
    ):
        settings = self.raster_settings
        if shs is not None or colors_precomp is None:
            _refuse("shs (SH colours)")
        if cov3D_precomp is not None or scales is None or rotations is None:
            _refuse("cov3D_precomp")
        if settings.prefiltered:
            _refuse("prefiltered=True")
        n = means3D.shape[0]
        if colors_precomp.shape != (n, NUM_CHANNELS):
            raise ValueError(
                f"diff_gaussian_rasterization_orthographic stand-in: colors_precomp must be "
                f"[N={n}, {NUM_CHANNELS}], got {tuple(colors_precomp.shape)}"
            )
        del means2D  # its gradient would come from the backward, which fails (module docstring)
        camera, radii = project_orthographic(
            means3D, rotations, scales * settings.scale_modifier, settings
        )
        background = torch.zeros(NUM_CHANNELS + 1, dtype=colors_precomp.dtype)
        background[:3] = settings.bg.detach().reshape(-1)[:3].to(colors_precomp.dtype)
        features = torch.cat(
            [colors_precomp, camera.depths.detach()[:, None].to(colors_precomp.dtype)], dim=1
        )
        bins = inria_bins(camera.means2d, radii, camera.depths, camera.width, camera.height)
        out = rasterize(camera, opacities.reshape(-1), features, background, bins=bins)
        image = out.image.permute(2, 0, 1)
        color, depth, alpha = image[:NUM_CHANNELS], image[NUM_CHANNELS:], out.alpha[None]
        if torch.is_grad_enabled() and any(t.requires_grad for t in (color, depth, alpha)):
            color, depth, alpha = _NoBackward.apply(color, depth, alpha)
        return color, radii.to(torch.int32), depth, alpha


__all__ = ["GaussianRasterizationSettings", "GaussianRasterizer", "project_orthographic"]
