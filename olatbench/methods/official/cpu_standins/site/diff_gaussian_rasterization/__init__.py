"""Stand-in for RNG's fork of diff_gaussian_rasterization in an official job with device=cpu
(olatbench.methods.official.cpu_standins.rng_rasterizer)."""

from olatbench.methods.official.cpu_standins.rng_rasterizer import (
    GaussianRasterizationSettings,
    GaussianRasterizer,
    rasterize_gaussians,
)

__all__ = ["GaussianRasterizationSettings", "GaussianRasterizer", "rasterize_gaussians"]
