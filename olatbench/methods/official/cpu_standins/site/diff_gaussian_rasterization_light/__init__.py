"""Stand-in for the authors' diff_gaussian_rasterization_light in an official job with device=cpu
(olatbench.methods.official.cpu_standins.light; the variant comes from $OLATBENCH_STANDIN_LIGHT)."""

from olatbench.methods.official.cpu_standins.light import (
    GaussianRasterizationSettings,
    GaussianRasterizer,
)

__all__ = ["GaussianRasterizationSettings", "GaussianRasterizer"]
