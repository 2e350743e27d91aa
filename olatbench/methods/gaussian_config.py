"""The config fields every Gaussian method shares (torch-free: specs and dry runs resolve configs without torch).

Iteration-valued fields are given at ``reference_iterations`` and scale with ``iterations`` (`steps`);
``densify_interval`` is a cadence and does not. A method's config subclasses `GaussianConfig`, redeclares the
shared fields whose default differs for it (a redeclared field keeps its place) and adds its own.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, ClassVar

from olatbench.methods.ranges import AT_LEAST_ONE, NON_NEGATIVE, OPEN_UNIT, POSITIVE, RATE, UNIT, Range, check_ranges


@dataclass
class GaussianConfig:
    """Run length, initialisation, loss, the 3DGS learning rates and density control (defaults: 3DGS's)."""

    label: ClassVar[str] = "Gaussian method"  # the method's name in messages
    ranges: ClassVar[dict[str, Range]] = {  # checked when the config is made (olatbench.methods.ranges)
        "iterations": AT_LEAST_ONE, "reference_iterations": AT_LEAST_ONE, "num_init_gaussians": AT_LEAST_ONE,
        "init_radius": POSITIVE, "init_opacity": OPEN_UNIT, "max_gaussians": AT_LEAST_ONE, "lambda_dssim": UNIT,
        "position_lr_init": RATE, "position_lr_final": RATE, "position_lr_delay_mult": NON_NEGATIVE,
        "position_lr_max_steps": AT_LEAST_ONE, "scaling_lr": RATE, "rotation_lr": RATE, "opacity_lr": RATE,
        "densify_from": NON_NEGATIVE, "densify_until": NON_NEGATIVE, "densify_interval": AT_LEAST_ONE,
        "densify_grad_threshold": NON_NEGATIVE, "opacity_reset_interval": AT_LEAST_ONE, "percent_dense": NON_NEGATIVE,
    }

    iterations: int = 30_000
    reference_iterations: int = 30_000
    # Initialisation and size.
    num_init_gaussians: int = 10_000
    # Uniform in the ball of init_radius around the origin (the paper's "unit sphere"), or with init_shape="box"
    # in the cube of half-side init_radius / 2 (the official codes' [-0.5, 0.5]³ at 1.0); None: the ball (and the
    # cube) around the point nearest every camera axis, fitted to the cameras (methods.initialisation).
    init_shape: str = "ball"
    init_radius: float | None = 1.0
    init_opacity: float = 0.1
    max_gaussians: int | None = None
    # Loss: (1 - λ) L1 + λ (1 - SSIM).
    lambda_dssim: float = 0.2
    # Learning rates (Adam, eps 1e-15); the position rate decays exponentially over position_lr_max_steps.
    position_lr_init: float = 1.6e-4  # × scene extent
    position_lr_final: float = 1.6e-6
    position_lr_delay_mult: float = 0.01
    position_lr_max_steps: int = 30_000
    scaling_lr: float = 5e-3
    rotation_lr: float = 1e-3
    opacity_lr: float = 0.05
    # Densification (3DGS).
    densify_from: int = 500
    densify_until: int = 15_000
    densify_interval: int = 100
    densify_grad_threshold: float = 2e-4
    opacity_reset_interval: int = 3_000
    percent_dense: float = 0.01

    def __post_init__(self) -> None:
        check_ranges(self, self.label)
        if self.init_shape not in ("ball", "box"):
            raise ValueError(f"{self.label} config: init_shape must be 'ball' or 'box', not {self.init_shape!r}")

    def steps(self, value: int) -> int:
        """An iteration count given at ``reference_iterations``, scaled to ``iterations``."""
        return round(value * self.iterations / self.reference_iterations)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-friendly values."""
        return asdict(self)
