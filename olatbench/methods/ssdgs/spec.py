"""SSD-GS as data (torch-free): what `olatbench methods`, the runner's plan and the reports know of
it."""

from __future__ import annotations

from olatbench.methods.resolve import DEFAULT_VARIANT
from olatbench.methods.spec import AblationGrid, MethodSpec
from olatbench.methods.ssdgs.presets import PRESETS

#: The paper's grids (``olatbench run --ablation NAME``): Composition A-F against the full model D,
#: Schedule H-K against the progressive physical schedule I (the default), and shadow on SSS against
#: the default.
ABLATIONS: dict[str, AblationGrid] = {
    "components": AblationGrid(
        tuple(f"ablation-{letter}" for letter in "ABCDEF"), reference="ablation-D"
    ),
    "schedule": AblationGrid(
        tuple(f"schedule-{letter}" for letter in "HIJK"), reference="schedule-I"
    ),
    "shadow-on-sss": AblationGrid((DEFAULT_VARIANT, "shadow-on-sss"), reference=DEFAULT_VARIANT),
}

SPEC = MethodSpec(
    name="ssdgs",
    description=(
        "SSD-GS (ICLR 2026): Lambert + ASG/Fresnel specular + dipole SSS + light-view shadow "
        "refined by an MLP, trained with a progressive schedule"
    ),
    implementation="olatbench.methods.ssdgs.method:SSDGS",
    config="olatbench.methods.ssdgs.config:SSDGSConfig",
    presets=PRESETS,
    ablations=ABLATIONS,
    outputs=("rgb", "diffuse", "specular", "sss", "shadow", "shadow_coarse", "alpha"),
    capabilities=frozenset({"relight", "refine_view", "components", "checkpoint", "init_points"}),
    scene_recipe="own-data",  # presets.py: the mini recipe over the official code's switches
    # as given, fitted during training, or refined
    evaluation="olatbench.methods.ssdgs.evaluation:SSDGSTestViews",
    authors="olatbench.methods.ssdgs.authors:AUTHORS",
)
