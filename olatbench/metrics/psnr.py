"""PSNR with a fixed peak: ``10 log10(peak² / MSE)``, MSE over all pixels and channels of one
image."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import torch

from olatbench.metrics._inputs import ArrayLike, check_same_shape, mask_to_n1hw, to_nchw, to_output
from olatbench.metrics.protocols import PSNR_MSE_FLOOR

if TYPE_CHECKING:
    from olatbench.metrics.protocols import Protocol
    from olatbench.metrics.registry import MetricBatch


def mse_torch(
    pred: torch.Tensor, gt: torch.Tensor, mask: torch.Tensor | None = None
) -> torch.Tensor:
    """Per-image mean squared error of (B, C, H, W) tensors -> (B,); ``mask`` (B, 1, H, W) weights
    pixels."""
    squared = (pred - gt) ** 2
    if mask is None:
        return squared.flatten(1).mean(1)
    weighted = (squared * mask).flatten(1).sum(1)
    return weighted / (mask.flatten(1).sum(1) * pred.shape[1])


def psnr_torch(
    pred: torch.Tensor, gt: torch.Tensor, mask: torch.Tensor | None = None, peak: float = 1.0
) -> torch.Tensor:
    """PSNR in dB of (B, C, H, W) tensors -> (B,); identical images give +inf."""
    return 10.0 * torch.log10(peak**2 / mse_torch(pred, gt, mask))


def floored_psnr(
    pred: torch.Tensor, gt: torch.Tensor, mask: torch.Tensor | None = None
) -> torch.Tensor:
    """The PSNR a protocol reports: ``10 log10(1 / MSE)`` per image of (B, C, H, W) tensors in
    [0, 1] -> (B,), the MSE in float64 (weighted by ``mask`` (B, 1, H, W) when given) and floored at
    `PSNR_MSE_FLOOR` (at most 100 dB)."""
    weights = None if mask is None else mask.double()
    mse = mse_torch(pred.double(), gt.double(), weights).clamp_min(PSNR_MSE_FLOOR)
    return 10.0 * torch.log10(1.0 / mse)


def psnr(
    pred: ArrayLike, gt: ArrayLike, mask: ArrayLike | None = None, peak: float = 1.0
) -> float | np.ndarray:
    """PSNR (dB) of channel-last images (H, W, C) or batches (B, H, W, C) with values in [0, peak].

    ``mask`` (H, W) or (B, H, W) in [0, 1] restricts (weights) the pixels of the MSE.
    Returns a float for one image, a (B,) array for a batch.
    """
    p, batched = to_nchw(pred, "pred")
    g, _ = to_nchw(gt, "gt", dtype=p.dtype, device=p.device)
    check_same_shape(p, g)
    with torch.no_grad():
        return to_output(psnr_torch(p, g, mask_to_n1hw(mask, p), peak), batched)


def protocol_psnr(batch: MetricBatch, protocol: Protocol) -> list[float]:
    """The ``psnr`` metric: ``10 log10(1 / MSE)`` per image, the MSE in float64 (mask-weighted for
    masked protocols) and floored at `PSNR_MSE_FLOOR` (at most 100 dB)."""
    return floored_psnr(batch.pred, batch.gt, batch.mask).tolist()
