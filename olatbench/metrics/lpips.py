"""LPIPS front end: [0, 1] channel-last images in, distances out; cached networks; optional onnxruntime.

The network expects [-1, 1]; ``lpips()`` maps ``x -> 2x - 1`` after a range guard that refuses values
outside [0, 1]. ``unit_range_compat=True`` feeds the [0, 1] images unchanged instead: the mistake of the
3DGS / SSD-GS ``lpipsPyTorch`` evaluation, available for the ``ssdgs`` compatibility protocol only.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import torch

from olatbench.metrics._inputs import ArrayLike, check_same_shape, check_unit_range, mask_to_n1hw, to_nchw, to_output
from olatbench.metrics.lpips_net import LPIPSNet
from olatbench.metrics.weights import load_lpips_net

BACKENDS: tuple[str, ...] = ("torch", "onnxruntime")
MIN_SIZE = {"alex": 31, "vgg": 16}  # smaller inputs leave an empty feature map in the backbone


@functools.lru_cache(maxsize=8)
def get_network(net: str = "alex", path: str | None = None, device: str = "cpu") -> LPIPSNet:
    """The LPIPSNet with real weights for ``net`` on ``device`` (cached); ``WeightsError`` if not installed."""
    return load_lpips_net(net, path).to(device)


def lpips_nchw(model: LPIPSNet, pred: torch.Tensor, gt: torch.Tensor, mask: torch.Tensor | None = None,
               unit_range_compat: bool = False, batch_size: int = 8) -> torch.Tensor:
    """LPIPS of (B, 3, H, W) images in [0, 1] -> (B,), in chunks of ``batch_size``.

    ``mask`` (B, 1, H, W): both images are multiplied by the mask (composited on black) first.
    """
    check_unit_range(pred, "pred")
    check_unit_range(gt, "gt")
    if min(pred.shape[-2:]) < MIN_SIZE[model.net]:
        raise ValueError(f"LPIPS-{model.net} needs images of at least {MIN_SIZE[model.net]}×{MIN_SIZE[model.net]} "
                         f"pixels, found {tuple(pred.shape[-2:])}")
    if mask is not None:
        pred, gt = pred * mask, gt * mask
    if not unit_range_compat:
        pred, gt = pred * 2 - 1, gt * 2 - 1
    dtype = next(model.parameters()).dtype
    device = next(model.parameters()).device
    out = [model(pred[i:i + batch_size].to(device, dtype), gt[i:i + batch_size].to(device, dtype))
           for i in range(0, pred.shape[0], batch_size)]
    return torch.cat(out).to(pred.device)


def lpips(pred: ArrayLike, gt: ArrayLike, net: str = "alex", mask: ArrayLike | None = None,
          weights: str | Path | None = None, device: str = "cpu", backend: str = "torch",
          unit_range_compat: bool = False) -> float | np.ndarray:
    """LPIPS v0.1 distance of channel-last images (H, W, 3) / (B, H, W, 3) in [0, 1] (numpy or torch).

    ``net``: ``alex`` or ``vgg``. ``weights``: explicit weights file/folder (else the lookup order of
    `olatbench.metrics.weights`); raises ``WeightsError`` when no weights are installed.
    ``backend``: ``torch`` or ``onnxruntime`` (`olatbench.metrics.lpips_onnx`). Float for one image,
    (B,) array for a batch.
    """
    p, batched = to_nchw(pred, "pred")
    g, _ = to_nchw(gt, "gt", dtype=p.dtype, device=p.device)
    check_same_shape(p, g)
    m = mask_to_n1hw(mask, p)
    if backend == "onnxruntime":
        from olatbench.metrics.lpips_onnx import onnx_lpips_nchw

        values = onnx_lpips_nchw(net, p, g, m, unit_range_compat, None if weights is None else str(weights))
        return to_output(values, batched)
    if backend != "torch":
        raise ValueError(f"unknown LPIPS backend {backend!r}; expected one of {BACKENDS}")
    model = get_network(net, None if weights is None else str(weights), device)
    with torch.no_grad():
        return to_output(lpips_nchw(model, p, g, m, unit_range_compat), batched)
