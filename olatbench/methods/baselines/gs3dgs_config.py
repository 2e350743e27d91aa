"""The 3DGS configuration (torch-free: `olatbench methods show 3dgs` and dry runs read it without torch)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

MAX_SH_DEGREE = 3  # the highest degree `olatbench.methods.baselines.sh` evaluates


@dataclass
class GS3DConfig:
    """3DGS settings. Iteration-valued fields are given at ``reference_iterations`` and scale with
    ``iterations``; ``densify_interval`` and ``sh_increase_interval`` are cadences and do not."""

    iterations: int = 30_000
    reference_iterations: int = 30_000
    sh_degree: int = 3
    sh_increase_interval: int = 1_000
    num_init_gaussians: int = 10_000
    init_radius: float | None = 1.0  # None: fitted to the cameras (see methods.initialisation.initial_ball)
    init_opacity: float = 0.1
    lambda_dssim: float = 0.2
    position_lr_init: float = 1.6e-4  # × scene extent
    position_lr_final: float = 1.6e-6
    position_lr_delay_mult: float = 0.01
    position_lr_max_steps: int = 30_000
    feature_lr: float = 2.5e-3  # DC; the higher-order coefficients use feature_lr / 20
    opacity_lr: float = 0.05
    scaling_lr: float = 5e-3
    rotation_lr: float = 1e-3
    densify_from: int = 500
    densify_until: int = 15_000
    densify_interval: int = 100
    densify_grad_threshold: float = 2e-4
    opacity_reset_interval: int = 3_000
    percent_dense: float = 0.01
    max_gaussians: int | None = None

    def __post_init__(self) -> None:
        if self.iterations <= 0 or self.reference_iterations <= 0:
            raise ValueError("3DGS config: iterations and reference_iterations must be positive")
        if not 0 <= self.sh_degree <= MAX_SH_DEGREE:
            raise ValueError(f"3DGS config: sh_degree must be in 0..{MAX_SH_DEGREE}, got {self.sh_degree}")

    def steps(self, value: int) -> int:
        """An iteration count given at ``reference_iterations``, scaled to ``iterations``."""
        return round(value * self.iterations / self.reference_iterations)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)
