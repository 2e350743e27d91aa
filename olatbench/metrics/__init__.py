"""Image metrics under named, versioned protocols: PSNR, SSIM, LPIPS (plain torch, real weights).

>>> from olatbench.metrics import psnr, ssim, lpips
>>> psnr(pred, gt), ssim(pred, gt), lpips(pred, gt, net="alex")   # (H, W, 3) float in [0, 1]
>>> from olatbench.metrics.protocols import get_protocol
>>> get_protocol("olatbench-v1").evaluate(pred, gt)

Training losses: `olatbench.metrics.ssim.ssim_torch` (differentiable) and `ssim_loss` (1 - SSIM; a C++
forward/backward for CPU tensors, `olatbench.metrics.ssim_cpu`).
"""

from olatbench.metrics.lpips import lpips
from olatbench.metrics.protocols import Protocol, get_protocol, protocol_names
from olatbench.metrics.psnr import psnr
from olatbench.metrics.ssim import ssim, ssim_loss, ssim_torch
from olatbench.metrics.weights import WeightsError

__all__ = ["Protocol", "WeightsError", "get_protocol", "lpips", "protocol_names", "psnr", "ssim", "ssim_loss",
           "ssim_torch"]
