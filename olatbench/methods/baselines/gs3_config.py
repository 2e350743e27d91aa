"""The GS³ configuration (torch-free: `olatbench methods show gs3` and dry runs read it without
torch)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from olatbench.methods.ranges import AT_LEAST_ONE, NON_NEGATIVE, POSITIVE, RATE, Range
from olatbench.methods.shading.config import ShadingConfig


@dataclass
class GS3Config(ShadingConfig):
    """GS³ settings (defaults: the official synthetic-scene script): the shared Gaussian and shading
    fields, GS³'s schedule, networks and rates."""

    label: ClassVar[str] = "GS³"
    iteration_fields: ClassVar[tuple[str, ...]] = (
        *ShadingConfig.iteration_fields,
        "shadow_from",
        "mlp_freeze_from",
        "specular_from",
        "asg_lobes_from",
    )
    ranges: ClassVar[dict[str, Range]] = {
        "shadow_from": NON_NEGATIVE,
        "mlp_freeze_from": NON_NEGATIVE,
        "specular_from": NON_NEGATIVE,
        "asg_lobes_from": NON_NEGATIVE,
        "other_hidden": AT_LEAST_ONE,
        "other_layers": AT_LEAST_ONE,
        "num_freqs": NON_NEGATIVE,
        "mlp_lr": RATE,
        "initial_shading": POSITIVE,
    }

    iterations: int = 100_000
    reference_iterations: int = 100_000
    max_gaussians: int | None = 550_000
    position_lr_max_steps: int = 50_000
    densify_until: int = 50_000
    # Schedule.
    shadow_from: int = 5_000  # official --unfreeze_iterations
    mlp_freeze_from: int = 9_000  # official --spcular_freeze_step
    specular_from: int = 16_000  # spcular_freeze_step + fit_linear_step
    asg_lobes_from: int = 22_000  # official --asg_freeze_step
    # Model.
    other_hidden: int = 128
    other_layers: int = 3
    num_freqs: int = 4
    # The two networks' layout: "torch", plain MLPs (the other-effects network with ReLU and biases,
    # the shadow network with one bias vector); "tiny_cuda_nn", the authors' FullyFusedMLP for both
    # (LeakyReLU, no biases, the input padded with ones; gs3_shading.OtherEffectsNetwork,
    # shading.shadow_mlp).
    network_layout: str = "torch"
    shadow_resolution: int | None = 256
    shadow_framing: str = "scene"
    # The brightest the initial diffuse shading albedo/π · I/d² may be at the initial ball's centre
    # under the median training light (GS3.prepare); None: the official albedo (softplus(0.5))
    # however bright the lights.
    initial_shading: float | None = 0.5
    # Learning rate of the networks.
    # constant: the official decay never applies (its group-name test is always false)
    mlp_lr: float = 1e-3

    def __post_init__(self) -> None:
        super().__post_init__()
        # gs3_shading.NETWORK_LAYOUTS (imports torch)
        if self.network_layout not in ("torch", "tiny_cuda_nn"):
            raise ValueError(
                f"GS³ config: network_layout must be 'torch' or 'tiny_cuda_nn', not "
                f"{self.network_layout!r}"
            )
        if not self.shadow_from <= self.mlp_freeze_from <= self.specular_from:
            raise ValueError("GS³ config: need shadow_from <= mlp_freeze_from <= specular_from")
