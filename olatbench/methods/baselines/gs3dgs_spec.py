"""3DGS as data (torch-free): presets per suite."""

from __future__ import annotations

from typing import Any

from olatbench.methods.spec import MethodSpec

# The 100K (NRHints, GS³) and 60K (SSS-GS) runs use the same position-decay and densification
# windows as the official SSD-GS / GS³ scripts ("all methods are trained for 100K iterations with
# identical settings").
PRESETS: dict[str, dict[str, Any]] = {
    "nrhints": {
        "iterations": 100_000,
        "reference_iterations": 100_000,
        "position_lr_max_steps": 70_000,
        "densify_until": 90_000,
        "max_gaussians": 550_000,
    },
    "gs3": {
        "iterations": 100_000,
        "reference_iterations": 100_000,
        "position_lr_max_steps": 70_000,
        "densify_until": 90_000,
        "max_gaussians": 550_000,
    },
    "sssgs": {
        "iterations": 60_000,
        "reference_iterations": 60_000,
        "position_lr_max_steps": 50_000,
        "densify_until": 50_000,
        "max_gaussians": 550_000,
    },
    # CPU-sized: 3000 steps, the 60K windows × 0.05, SH degree raised every 250 steps, few
    # Gaussians.
    "mini": {
        "iterations": 3_000,
        "reference_iterations": 60_000,
        "num_init_gaussians": 2_000,
        "init_radius": None,
        "max_gaussians": 12_000,
        "sh_increase_interval": 250,
        "position_lr_max_steps": 60_000,
        "densify_from": 4_000,
        "densify_until": 44_000,
        "opacity_reset_interval": 30_000,
    },
}


SPEC = MethodSpec(
    name="3dgs",
    description=(
        "3D Gaussian Splatting (Kerbl et al. 2023), SH degree 3, ignores the light: the lower "
        "bound for relighting"
    ),
    implementation="olatbench.methods.baselines.gs3dgs:GaussianSplatting3D",
    config="olatbench.methods.baselines.gs3dgs_config:GS3DConfig",
    presets=PRESETS,
    outputs=("rgb", "alpha"),
    capabilities=frozenset({"checkpoint", "init_points"}),
    scene_recipe="mini",
)
