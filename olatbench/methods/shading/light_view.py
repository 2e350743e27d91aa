"""The light-view pass's options for one view, from a shading config: its size, framing, averaging
mode and self-shadow offset (`ShadingConfig.light_view_size`, ``shadow_framing``, ``shadow_mode``,
``shadow_depth_offset``), shared by SSD-GS and GS³."""

from __future__ import annotations

from typing import Any

import torch

from olatbench.gaussians.shadow import camera_matched_focal
from olatbench.methods.shading.config import ShadingConfig


def light_view_options(
    config: ShadingConfig,
    K: torch.Tensor,
    width: int,
    height: int,
    camera_position: torch.Tensor,
    light_position: torch.Tensor,
    target: torch.Tensor,
) -> dict[str, Any]:
    """`olatbench.gaussians.shadow.shadow_gather` keyword options for a view of ``width`` ×
    ``height`` px with intrinsics ``K`` (3, 3) seen from ``camera_position`` (3,), lit from
    ``light_position`` (3,), the light view looking at ``target`` (3,; the Gaussians' mean): with
    ``shadow_framing="camera"`` the focal length matches the viewing camera's pixel scale
    (`camera_matched_focal`), with ``"scene"`` the pass fits the scene itself."""
    resolution = config.light_view_size(width, height)
    focal = None
    if config.shadow_framing == "camera":
        focal = camera_matched_focal(
            K[0, 0], width, resolution, camera_position, light_position, target
        )
    return {
        "resolution": resolution,
        "focal_px": focal,
        "mode": config.shadow_mode,
        "depth_offset": config.shadow_depth_offset,
    }
