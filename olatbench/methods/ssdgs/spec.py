"""SSD-GS as data (torch-free): what `olatbench methods`, the runner's plan and the reports know of it."""

from __future__ import annotations

from olatbench.methods.spec import DEFAULT_VARIANT, MethodSpec
from olatbench.methods.ssdgs.presets import PRESETS

#: The paper's grids (``olatbench run --ablation NAME``): Composition A-F, Schedule H-K, and shadow on SSS.
ABLATIONS: dict[str, tuple[str, ...]] = {
    "components": tuple(f"ablation-{letter}" for letter in "ABCDEF"),
    "schedule": tuple(f"schedule-{letter}" for letter in "HIJK"),
    "shadow-on-sss": (DEFAULT_VARIANT, "shadow-on-sss"),
}

SPEC = MethodSpec(
    name="ssdgs",
    description=("SSD-GS (ICLR 2026): Lambert + ASG/Fresnel specular + dipole SSS + light-view shadow refined by "
                 "an MLP, trained with a progressive schedule"),
    implementation="olatbench.methods.ssdgs.method:SSDGS",
    config="olatbench.methods.ssdgs.config:SSDGSConfig",
    presets=PRESETS,
    ablations=ABLATIONS,
    outputs=("rgb", "diffuse", "specular", "sss", "shadow", "shadow_coarse", "alpha"),
    capabilities=frozenset({"relight", "refine_view", "components", "checkpoint", "init_points"}),
    scene_recipe="own-data",  # presets.py: the mini recipe over the official code's switches
    evaluation="olatbench.methods.ssdgs.evaluation:SSDGSTestViews",  # as given, fitted during training, or refined
)
