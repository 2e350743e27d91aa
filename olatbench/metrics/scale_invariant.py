"""The scale-invariant PSNR (``psnr_si``): PSNR over the object after the per-channel least-squares
scale that best maps the render onto the ground truth, as Stanford-ORB's relighting benchmark scores
renders whose light units are unknown.

For each image and channel ``c``, over the object mask ``m`` (the ground truth's alpha, weights in
[0, 1]): ``s_c = Σ m·gt_c·pred_c / Σ m·pred_c²`` (1 where the render is black there), then
``PSNR = 10 log10(1 / MSE)`` with ``MSE = Σ m·(gt - clip(s·pred, 0, 1))² / (3 Σ m)``.

The scale is fitted in the space the protocol scores in (the data's: sRGB for the NRHints-format
suites, gamma 2.2 for GS³'s), on the images as the protocol prepared them (clipped, quantised):
there it is the per-channel gain that minimises the very squared error PSNR measures (before the
clip to the display range), and a light-unit change, a gain ``k`` in linear light, is a gain of
``k^(1/2.2)`` of a gamma-2.2 image exactly and of an sRGB image nearly (over linear values 0.02 … 1,
a linear gain of 2 is an sRGB gain of 1.36 … 1.46, one of 0.5 of 0.66 … 0.74; in the linear toe
below 0.0031 it is ``k`` itself). The metrics see the protocol's images, not the space they are in,
so the fit cannot be made in linear light here.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import torch

from olatbench.metrics.psnr import floored_psnr

if TYPE_CHECKING:
    from olatbench.metrics.protocols import Protocol
    from olatbench.metrics.registry import MetricBatch


def least_squares_scale(pred: torch.Tensor, gt: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Per image and channel, the scale ``s`` minimising ``Σ m (gt - s·pred)²``: (B, C, H, W)
    images, (B, 1, H, W) weights -> (B, C, 1, 1); 1 where the render is zero over the mask."""
    numerator = (mask * gt * pred).sum(dim=(2, 3), keepdim=True)
    denominator = (mask * pred * pred).sum(dim=(2, 3), keepdim=True)
    return torch.where(
        denominator > 0,
        numerator / denominator.clamp_min(torch.finfo(pred.dtype).tiny),
        torch.ones_like(denominator),
    )


def scale_invariant_psnr(pred: torch.Tensor, gt: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """The scale-invariant PSNR (dB, module docstring) of (B, C, H, W) images in [0, 1] over
    (B, 1, H, W) weights, in float64 -> (B,); at most 100 dB (MSE floored at `PSNR_MSE_FLOOR`)."""
    pred, gt, mask = pred.double(), gt.double(), mask.double()
    scaled = (least_squares_scale(pred, gt, mask) * pred).clamp(0.0, 1.0)
    return floored_psnr(scaled, gt, mask)


def _alpha(batch: MetricBatch, protocol: Protocol, name: str) -> torch.Tensor:
    if batch.alpha is None:
        raise ValueError(
            f"protocol {protocol.id} lists {name}, which needs the ground truth's alpha: set "
            "object_mask=True"
        )
    return batch.alpha


def protocol_psnr_si(batch: MetricBatch, protocol: Protocol) -> list[float]:
    """The ``psnr_si`` metric over the ground truth's alpha (``batch.alpha``: a protocol with
    ``object_mask`` or ``masked``)."""
    return scale_invariant_psnr(batch.pred, batch.gt, _alpha(batch, protocol, "psnr_si")).tolist()


def protocol_psnr_object(batch: MetricBatch, protocol: Protocol) -> list[float]:
    """The ``psnr_object`` metric: PSNR over the ground truth's alpha without a scale, so that
    ``psnr_si`` minus it is what the scale alone buys (the plain ``psnr`` also counts the empty
    background)."""
    return floored_psnr(batch.pred, batch.gt, _alpha(batch, protocol, "psnr_object")).tolist()
