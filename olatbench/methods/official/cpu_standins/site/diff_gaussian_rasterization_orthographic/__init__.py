"""Stand-in for RNG's diff_gaussian_rasterization_orthographic in an official job with device=cpu
(olatbench.methods.official.cpu_standins.rng_orthographic)."""

from olatbench.methods.official.cpu_standins.rng_orthographic import (
    GaussianRasterizationSettings,
    GaussianRasterizer,
)

__all__ = ["GaussianRasterizationSettings", "GaussianRasterizer"]
