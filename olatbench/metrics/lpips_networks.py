"""The torch LPIPS networks with real weights, loaded once per (net, weights, device): the one cache
both LPIPS backends read (`olatbench.metrics.lpips` runs it, `olatbench.metrics.lpips_onnx` exports
it), so neither imports the other's module."""

from __future__ import annotations

import functools

import torch

from olatbench.metrics.lpips_net import LPIPSNet
from olatbench.metrics.weights import load_lpips_net


@functools.lru_cache(maxsize=8)
def get_network(net: str = "alex", path: str | None = None, device: str = "cpu") -> LPIPSNet:
    """The torch LPIPSNet with real weights for ``net`` on ``device`` (cached); ``WeightsError`` if
    not installed."""
    return load_lpips_net(net, path).to(device).to(memory_format=torch.channels_last)
