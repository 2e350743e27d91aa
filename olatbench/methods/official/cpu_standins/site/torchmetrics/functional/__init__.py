"""Stand-in for torchmetrics.functional
(olatbench.methods.official.cpu_standins.torchmetrics_image)."""

from . import image

__all__ = ["image"]
