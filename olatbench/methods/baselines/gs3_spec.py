"""GS³ as data (torch-free): presets per suite and what the method renders."""

from __future__ import annotations

from typing import Any

from olatbench.methods.authors import OFFICIAL_VARIANT
from olatbench.methods.baselines.gs3_authors import AUTHORS
from olatbench.methods.spec import MethodSpec

PRESETS: dict[str, dict[str, Any]] = {
    # GS³'s own scripts: 100K iterations, position decay and densification over the first 50K.
    "nrhints": {"iterations": 100_000, "reference_iterations": 100_000},
    "gs3": {"iterations": 100_000, "reference_iterations": 100_000},
    # SSS-GS: 60K iterations with the same absolute phase thresholds (as SSD-GS's 60K runs).
    "sssgs": {"iterations": 60_000, "reference_iterations": 60_000},
    # CPU-sized: the 60K schedule compressed 20× into 3000 steps, few Gaussians, a small light-view
    # pass with SSD-GS's mini self-shadow offset (docs/ssdgs.md; measured here on diffuse_shadow:
    # 19.22 -> 20.80 dB).
    "mini": {
        "iterations": 3_000,
        "reference_iterations": 60_000,
        "num_init_gaussians": 2_000,
        "init_radius": None,
        "max_gaussians": 12_000,
        "shadow_resolution": 96,
        "shadow_depth_offset": 1.8,
        "num_asg": 4,
        "other_hidden": 64,
        "position_lr_max_steps": 60_000,
        "densify_from": 4_000,
        "densify_until": 44_000,
        "opacity_reset_interval": 30_000,
        "asg_lr_decay_from": 40_000,
        "asg_lr_max_steps": 20_000,
    },
    # The authors' code on any suite and length (`olatbench.methods.baselines.gs3_authors`): every
    # field with a counterpart in their code takes their value, over the suite preset's run
    # settings.
    OFFICIAL_VARIANT: AUTHORS.preset(),
}


SPEC = MethodSpec(
    name="gs3",
    description=(
        "GS³ (Bi et al. 2024): Lambert + ASG/Fresnel, MLP-refined light-view shadow and "
        "other-effects MLP, composited in screen space as I·V + O"
    ),
    implementation="olatbench.methods.baselines.gs3:GS3",
    config="olatbench.methods.baselines.gs3_config:GS3Config",
    presets=PRESETS,
    outputs=("rgb", "diffuse", "specular", "shading", "shadow", "shadow_coarse", "other", "alpha"),
    capabilities=frozenset({"relight", "components", "checkpoint", "init_points"}),
    scene_recipe="mini",
    authors="olatbench.methods.baselines.gs3_authors:AUTHORS",
)
