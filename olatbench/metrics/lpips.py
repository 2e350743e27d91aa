"""LPIPS front end: [0, 1] channel-last images in, distances out; cached networks; torch or
onnxruntime.

The network expects [-1, 1]; ``lpips()`` maps ``x -> 2x - 1`` after a range guard that refuses
values outside [0, 1]. ``unit_range_compat=True`` feeds the [0, 1] images unchanged instead: the
mistake of the 3DGS / SSD-GS ``lpipsPyTorch`` evaluation, available for the ``ssdgs`` compatibility
protocol only.

Backends: ``torch`` (`LPIPSNet`, channels-last memory format, any device), ``onnxruntime``
(CPU, `olatbench.metrics.lpips_onnx`), ``auto`` (onnxruntime on the CPU when usable, else torch; the
environment variable ``OLATBENCH_LPIPS_BACKEND`` overrides ``auto``).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from olatbench.metrics._inputs import (
    ArrayLike,
    check_same_shape,
    check_unit_range,
    mask_to_n1hw,
    to_nchw,
    to_output,
)
from olatbench.metrics.lpips_net import LPIPSNet
from olatbench.metrics.lpips_networks import get_network
from olatbench.metrics.lpips_onnx import get_onnx_network, onnx_usable

BACKENDS: tuple[str, ...] = ("auto", "torch", "onnxruntime")
MIN_SIZE = {"alex": 31, "vgg": 16}  # smaller inputs leave an empty feature map in the backbone
Runner = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]


def clear_caches() -> None:
    """Forget loaded networks (torch and onnxruntime), e.g. after installing weights or in tests."""
    get_network.cache_clear()
    get_onnx_network.cache_clear()


def resolve_backend(
    backend: str = "auto", device: str = "cpu", net: str = "alex", path: str | None = None
) -> str:
    """``torch`` or ``onnxruntime`` for a requested backend
    (``auto`` honours ``OLATBENCH_LPIPS_BACKEND``)."""
    if backend == "auto":
        backend = os.environ.get("OLATBENCH_LPIPS_BACKEND", "auto")
    if backend not in BACKENDS:
        raise ValueError(f"unknown LPIPS backend {backend!r}; expected one of {BACKENDS}")
    if backend == "auto":
        return "onnxruntime" if str(device) == "cpu" and onnx_usable(net, path) else "torch"
    return backend


def get_runner(
    net: str = "alex", path: str | None = None, device: str = "cpu", backend: str = "auto"
) -> Runner:
    """A callable ``(x, y) -> (B,)`` on [-1, 1] NCHW images with real weights
    (``WeightsError`` if missing)."""
    if resolve_backend(backend, device, net, path) == "onnxruntime":
        return get_onnx_network(net, path)
    return get_network(net, path, device)


def lpips_nchw(
    model: Runner,
    pred: torch.Tensor,
    gt: torch.Tensor,
    mask: torch.Tensor | None = None,
    unit_range_compat: bool = False,
    batch_size: int = 8,
) -> torch.Tensor:
    """LPIPS of (B, 3, H, W) images in [0, 1] -> (B,), in chunks of ``batch_size``.

    ``model``: an `LPIPSNet` or `OnnxLPIPS`. ``mask`` (B, 1, H, W): both images are multiplied by
    the mask (composited on black) first.
    """
    net = model.net
    check_unit_range(pred, "pred")
    check_unit_range(gt, "gt")
    if min(pred.shape[-2:]) < MIN_SIZE[net]:
        raise ValueError(
            f"LPIPS-{net} needs images of at least {MIN_SIZE[net]}×{MIN_SIZE[net]} pixels, "
            f"found {tuple(pred.shape[-2:])}"
        )
    if mask is not None:
        pred, gt = pred * mask, gt * mask
    if not unit_range_compat:
        pred, gt = pred * 2 - 1, gt * 2 - 1
    if isinstance(model, LPIPSNet):
        parameter = next(model.parameters())

        def prepare(t: torch.Tensor) -> torch.Tensor:
            return t.to(parameter.device, parameter.dtype).contiguous(
                memory_format=torch.channels_last
            )
    else:

        def prepare(t: torch.Tensor) -> torch.Tensor:
            return t

    out = [
        model(prepare(pred[i : i + batch_size]), prepare(gt[i : i + batch_size]))
        for i in range(0, pred.shape[0], batch_size)
    ]
    return torch.cat(out).to(pred.device)


def lpips(
    pred: ArrayLike,
    gt: ArrayLike,
    net: str = "alex",
    mask: ArrayLike | None = None,
    weights: str | Path | None = None,
    device: str = "cpu",
    backend: str = "auto",
    unit_range_compat: bool = False,
) -> float | np.ndarray:
    """LPIPS v0.1 distance of channel-last images (H, W, 3) / (B, H, W, 3) in [0, 1]
    (numpy or torch).

    ``net``: ``alex`` or ``vgg``. ``weights``: explicit weights file/folder (else the lookup order
    of `olatbench.metrics.weights`); raises ``WeightsError`` when no weights are installed. Float
    for one image, (B,) array for a batch.
    """
    p, batched = to_nchw(pred, "pred")
    g, _ = to_nchw(gt, "gt", dtype=p.dtype, device=p.device)
    check_same_shape(p, g)
    runner = get_runner(net, None if weights is None else str(weights), device, backend)
    with torch.no_grad():
        return to_output(
            lpips_nchw(runner, p, g, mask_to_n1hw(mask, p), unit_range_compat), batched
        )
