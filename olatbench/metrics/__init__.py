"""Image metrics under named, versioned protocols: PSNR, SSIM, LPIPS (plain torch, real weights).

>>> from olatbench.metrics import psnr, ssim, lpips
>>> psnr(pred, gt), ssim(pred, gt), lpips(pred, gt, net="alex")   # (H, W, 3) float in [0, 1]
>>> from olatbench.metrics.protocols import get_protocol
>>> get_protocol("olatbench-v1").evaluate(pred, gt)

Training losses: `olatbench.metrics.ssim.ssim_torch` (differentiable) and `ssim_loss` (1 - SSIM; a
C++ forward/backward for CPU tensors, `olatbench.metrics.ssim_cpu`).

The package imports lazily (PEP 562): the protocol registry (`olatbench.metrics.protocols`) loads
without torch, so plans and `olatbench metrics` listings stay light; the metric functions load torch
on first use.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import Any

_EXPORTS = {
    "lpips": "olatbench.metrics.lpips",
    "Protocol": "olatbench.metrics.protocols",
    "get_protocol": "olatbench.metrics.protocols",
    "protocol_names": "olatbench.metrics.protocols",
    "psnr": "olatbench.metrics.psnr",
    "ssim": "olatbench.metrics.ssim",
    "ssim_loss": "olatbench.metrics.ssim",
    "ssim_torch": "olatbench.metrics.ssim",
    "WeightsError": "olatbench.metrics.weights",
}

__all__ = sorted(_EXPORTS)


class _LazyMetrics(types.ModuleType):
    """The package module: its exported names resolve on access. ``psnr``, ``ssim`` and ``lpips``
    are also submodule names, which the import system binds on the package once a submodule loads;
    resolving on every access keeps ``olatbench.metrics.ssim`` the function, as an eager
    ``from ... import ssim`` did."""

    def __getattribute__(self, name: str) -> Any:
        if name in _EXPORTS:
            return getattr(importlib.import_module(_EXPORTS[name]), name)
        return super().__getattribute__(name)


sys.modules[__name__].__class__ = _LazyMetrics
