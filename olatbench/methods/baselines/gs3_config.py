"""The GS³ configuration (torch-free: `olatbench methods show gs3` and dry runs read it without torch)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any


@dataclass
class GS3Config:
    """GS³ settings (defaults: the official synthetic-scene script). Iteration-valued fields are given at
    ``reference_iterations`` and scale with ``iterations``; ``densify_interval`` is a cadence and does not."""

    iterations: int = 100_000
    reference_iterations: int = 100_000
    # Schedule.
    shadow_from: int = 5_000  # official --unfreeze_iterations
    mlp_freeze_from: int = 9_000  # official --spcular_freeze_step
    specular_from: int = 16_000  # spcular_freeze_step + fit_linear_step
    asg_lobes_from: int = 22_000  # official --asg_freeze_step
    # Model.
    num_asg: int = 8
    material_dim: int = 6
    shadow_hidden: int = 32
    shadow_layers: int = 3
    other_hidden: int = 128
    other_layers: int = 3
    num_freqs: int = 4
    fresnel_f0: float = 0.04
    shadow_resolution: int = 256
    shadow_depth_offset: float = 0.0  # light-view self-shadow offset (squared-distance units), as SSD-GS's
    num_init_gaussians: int = 10_000
    init_radius: float | None = 1.0  # None: fitted to the cameras (see methods.initialisation.initial_ball)
    init_opacity: float = 0.1
    max_gaussians: int | None = 550_000
    # Loss and learning rates (Adam, eps 1e-15).
    lambda_dssim: float = 0.2
    position_lr_init: float = 1.6e-4  # × scene extent
    position_lr_final: float = 1.6e-6
    position_lr_delay_mult: float = 0.01
    position_lr_max_steps: int = 50_000
    scaling_lr: float = 5e-3
    rotation_lr: float = 1e-3
    opacity_lr: float = 0.05
    colour_lr: float = 0.01  # k_d and k_s
    asg_lr_init: float = 0.01  # ASG weights and lobes; the learned shading frame uses the same decay
    asg_lr_final: float = 1e-4
    asg_lr_decay_from: int = 40_000
    asg_lr_max_steps: int = 50_000
    mlp_lr: float = 1e-3  # constant: the official decay never applies (its group-name test is always false)
    # Densification (3DGS).
    densify_from: int = 500
    densify_until: int = 50_000
    densify_interval: int = 100
    densify_grad_threshold: float = 2e-4
    opacity_reset_interval: int = 3_000
    percent_dense: float = 0.01

    def __post_init__(self) -> None:
        if self.iterations <= 0 or self.reference_iterations <= 0:
            raise ValueError("GS³ config: iterations and reference_iterations must be positive")
        if not self.shadow_from <= self.mlp_freeze_from <= self.specular_from:
            raise ValueError("GS³ config: need shadow_from <= mlp_freeze_from <= specular_from")

    def steps(self, value: int) -> int:
        """An iteration count given at ``reference_iterations``, scaled to ``iterations``."""
        return round(value * self.iterations / self.reference_iterations)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)
