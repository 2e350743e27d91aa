"""The config fields every Gaussian method shares (torch-free: specs and dry runs resolve configs
without torch).

Iteration-valued fields are given at ``reference_iterations`` and scale with ``iterations``
(`steps`); ``densify_interval`` is a cadence and does not. Density control keeps floors when a run
is shortened (`GaussianConfig.density_windows`). A method's config subclasses `GaussianConfig`,
redeclares the shared fields whose default differs for it (a redeclared field keeps its place) and
adds its own.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any, ClassVar

from olatbench.methods.ranges import (
    AT_LEAST_ONE,
    NON_NEGATIVE,
    OPEN_UNIT,
    POSITIVE,
    RATE,
    UNIT,
    Range,
    check_ranges,
)
from olatbench.methods.run_length import scaled_steps

#: Densification steps the density-control window holds at least: a shortened run densifies more
#: often rather than once or never (the 3DGS window holds 145 at 30K steps, the mini presets' 20 at
#: 3000).
MIN_DENSIFICATIONS = 10
#: An opacity reset sets every opacity to 0.01 (logit -4.6); Adam moves a logit by about
#: ``opacity_lr`` per step, so climbing back to 0.5 takes about 4.6 / opacity_lr steps
#: (92 at 3DGS's 0.05). Resets come at least three such climbs apart, else the Gaussians never
#: recover and pruning removes them (a 200-step 3DGS run that reset every 6 steps fell from 10,000
#: Gaussians to 627).
OPACITY_RECOVERY_CLIMBS = 3
_RESET_LOGIT_CLIMB = math.log(99.0)  # logit(0.5) - logit(0.01)


@dataclass(frozen=True)
class DensityWindows:
    """The density-control schedule of one run, in steps: densify every ``interval`` steps in
    (``densify_from``, ``densify_until``), reset opacities every ``opacity_reset_interval`` steps in
    that window."""

    densify_from: int
    densify_until: int
    interval: int
    opacity_reset_interval: int


@dataclass
class GaussianConfig:
    """Run length, initialisation, loss, the 3DGS learning rates and density control
    (defaults: 3DGS's)."""

    label: ClassVar[str] = "Gaussian method"  # the method's name in messages
    # the fields given at reference_iterations, which a run takes scaled to its length (`steps`)
    iteration_fields: ClassVar[tuple[str, ...]] = (
        "position_lr_max_steps",
        "densify_from",
        "densify_until",
        "opacity_reset_interval",
    )
    # checked when the config is made (olatbench.methods.ranges)
    ranges: ClassVar[dict[str, Range]] = {
        "iterations": AT_LEAST_ONE,
        "reference_iterations": AT_LEAST_ONE,
        "num_init_gaussians": AT_LEAST_ONE,
        "init_radius": POSITIVE,
        "init_opacity": OPEN_UNIT,
        "max_gaussians": AT_LEAST_ONE,
        "lambda_dssim": UNIT,
        "position_lr_init": RATE,
        "position_lr_final": RATE,
        "position_lr_delay_mult": NON_NEGATIVE,
        "position_lr_max_steps": AT_LEAST_ONE,
        "scaling_lr": RATE,
        "rotation_lr": RATE,
        "opacity_lr": RATE,
        "densify_from": NON_NEGATIVE,
        "densify_until": NON_NEGATIVE,
        "densify_interval": AT_LEAST_ONE,
        "densify_grad_threshold": NON_NEGATIVE,
        "opacity_reset_interval": AT_LEAST_ONE,
        "percent_dense": NON_NEGATIVE,
    }

    iterations: int = 30_000
    reference_iterations: int = 30_000
    # Initialisation and size.
    num_init_gaussians: int = 10_000
    # Uniform in the ball of init_radius around the origin (the paper's "unit sphere"), or with
    # init_shape="box" in the cube of half-side init_radius / 2 (the official codes' [-0.5, 0.5]³ at
    # 1.0); None: the ball (and the cube) around the point nearest every camera axis, fitted to the
    # cameras (methods.initialisation).
    init_shape: str = "ball"
    init_radius: float | None = 1.0
    init_opacity: float = 0.1
    max_gaussians: int | None = None
    # Loss: (1 - λ) L1 + λ (1 - SSIM).
    lambda_dssim: float = 0.2
    # Learning rates (Adam, eps 1e-15); the position rate decays exponentially over
    # position_lr_max_steps.
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
            raise ValueError(
                f"{self.label} config: init_shape must be 'ball' or 'box', not {self.init_shape!r}"
            )

    def steps(self, value: int) -> int:
        """An iteration count given at ``reference_iterations``, scaled to ``iterations``
        (`scaled_steps`, the rule the official runner applies to the authors' flags)."""
        return scaled_steps(value, self.iterations, self.reference_iterations)

    def density_windows(self) -> DensityWindows:
        """The densification window and opacity-reset interval scaled to ``iterations``
        (`steps`, at least 1 each), with two floors that only bind in shortened runs
        (``iterations < reference_iterations``): the window holds at least `MIN_DENSIFICATIONS`
        densifications (the interval shrinks to fit), and resets come at least
        `OPACITY_RECOVERY_CLIMBS` times the steps a reset opacity needs to recover at ``opacity_lr``
        apart (a run shorter than that resets never)."""
        start = max(1, self.steps(self.densify_from))
        until = max(1, self.steps(self.densify_until))
        interval = self.densify_interval
        if self.iterations >= self.reference_iterations:  # not shortened: the windows as given
            return DensityWindows(
                densify_from=start,
                densify_until=until,
                interval=interval,
                opacity_reset_interval=max(1, self.steps(self.opacity_reset_interval)),
            )
        if until - start >= MIN_DENSIFICATIONS:
            interval = min(interval, (until - start) // MIN_DENSIFICATIONS)
        if self.opacity_lr > 0:
            recovery = math.ceil(OPACITY_RECOVERY_CLIMBS * _RESET_LOGIT_CLIMB / self.opacity_lr)
        else:  # frozen opacities never recover from a reset: none comes within the run
            recovery = self.iterations + 1
        reset = max(1, self.steps(self.opacity_reset_interval), recovery)
        return DensityWindows(
            densify_from=start, densify_until=until, interval=interval, opacity_reset_interval=reset
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-friendly values."""
        return asdict(self)
