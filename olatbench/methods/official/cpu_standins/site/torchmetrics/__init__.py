"""Stand-in for torchmetrics in an official job of rng-official with device=cpu: only the PSNR, SSIM
and LPIPS of ``torchmetrics.functional.image``
(olatbench.methods.official.cpu_standins.torchmetrics_image)."""

from . import functional

__version__ = "1.9.0+olatbench.cpu"
__all__ = ["functional"]
