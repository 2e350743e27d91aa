"""Stand-in for gsplat 1.1.1 in an official job with device=cpu
(olatbench.methods.official.cpu_standins)."""

from olatbench.methods.official.cpu_standins.rasterization import rasterization

__version__ = "1.1.1+olatbench.cpu"
__all__ = ["rasterization"]
