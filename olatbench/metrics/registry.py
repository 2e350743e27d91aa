"""Metrics as data: each one's name (its key in results.json), title, direction and batch function.

A protocol (`olatbench.metrics.protocols.Protocol`) lists the metric names it reports; it computes
each with the metric's function, and the reports title and rank its columns from here
(`olatbench.reports.layouts`). Adding a metric is one module (its batch function) and one line (its
`Metric` in `BUILTIN_METRICS`, or a `register_metric` call), then a protocol that lists it: a new
protocol id or version, since a protocol's numbers never change (docs/metrics-and-formats.md).

The registry imports no torch: a metric's function is a ``"module:function"`` reference, imported
when a batch is scored. The function takes a `MetricBatch` and the protocol and returns one value
per image (None: not computable, e.g. missing weights).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

if TYPE_CHECKING:
    import torch

Direction = Literal["max", "min"]
ARROWS: dict[str, str] = {"max": "↑", "min": "↓"}


@dataclass
class MetricBatch:
    """One batch of image pairs as a protocol scores them: ``pred`` and ``gt`` (B, 3, H, W) float32
    in [0, 1] (already clipped and quantised by the protocol), ``mask`` (B, 1, H, W) in [0, 1] for
    masked protocols (else None), on ``device``; ``cache`` holds what several metrics share (e.g.
    one LPIPS pass for ``lpips`` and ``lpips_<net>``); ``alpha`` (B, 1, H, W) the ground truth's
    coverage for protocols with ``object_mask`` or ``masked`` (else None): the object's extent for a
    metric that needs it (``psnr_si`` fits its scale there) without weighting the others."""

    pred: torch.Tensor
    gt: torch.Tensor
    mask: torch.Tensor | None
    device: str
    cache: dict[str, Any] = field(default_factory=dict)
    alpha: torch.Tensor | None = None

    def __len__(self) -> int:
        return int(self.pred.shape[0])


@dataclass(frozen=True)
class Metric:
    """``name``: the key in results.json and in a protocol's list; ``title``: the column heading
    (the reports add the direction's arrow); ``direction``: "max" (higher is better) or "min";
    ``function``: ``"module:function"`` of ``(batch: MetricBatch, protocol) -> list[float | None]``
    (one value per image)."""

    name: str
    title: str
    direction: Direction
    function: str
    description: str = ""

    def __post_init__(self) -> None:
        if self.direction not in ARROWS:
            raise ValueError(
                f"metric {self.name!r}: direction must be 'max' or 'min', not {self.direction!r}"
            )
        module, sep, attribute = self.function.partition(":")
        if not (module and sep and attribute):
            raise ValueError(
                f"metric {self.name!r}: function {self.function!r} is not of the form "
                "'module:function'"
            )

    @property
    def heading(self) -> str:
        """The title with the direction's arrow (``PSNR ↑``)."""
        return f"{self.title} {ARROWS[self.direction]}"

    def load(self) -> Callable[..., list[float | None]]:
        """The batch function (imports its module)."""
        module_name, _, name = self.function.partition(":")
        return getattr(importlib.import_module(module_name), name)


#: The built-in metrics: one line each.
BUILTIN_METRICS: tuple[Metric, ...] = (
    Metric(
        "psnr",
        "PSNR",
        "max",
        "olatbench.metrics.psnr:protocol_psnr",
        "10 log10(1 / MSE), MSE floored",
    ),
    Metric(
        "ssim", "SSIM", "max", "olatbench.metrics.ssim:protocol_ssim", "the protocol's SSIM variant"
    ),
    Metric(
        "lpips",
        "LPIPS",
        "min",
        "olatbench.metrics.lpips_metric:protocol_lpips",
        "LPIPS of the primary network",
    ),
    Metric(
        "lpips_alex",
        "LPIPS (Alex)",
        "min",
        "olatbench.metrics.lpips_metric:protocol_lpips_alex",
        "LPIPS-AlexNet",
    ),
    Metric(
        "lpips_vgg",
        "LPIPS (VGG)",
        "min",
        "olatbench.metrics.lpips_metric:protocol_lpips_vgg",
        "LPIPS-VGG16",
    ),
    Metric(
        "flip",
        "ꟻLIP",
        "min",
        "olatbench.metrics.flip:protocol_flip",
        "LDR-ꟻLIP (NVIDIA), mean error",
    ),
    Metric(
        "psnr_object",
        "PSNR (object)",
        "max",
        "olatbench.metrics.scale_invariant:protocol_psnr_object",
        "PSNR over the ground truth's alpha",
    ),
    Metric(
        "psnr_si",
        "PSNR (scale-inv.)",
        "max",
        "olatbench.metrics.scale_invariant:protocol_psnr_si",
        "PSNR over the object after a per-channel least-squares scale (Stanford-ORB)",
    ),
)

_METRICS: dict[str, Metric] = {metric.name: metric for metric in BUILTIN_METRICS}


def register_metric(metric: Metric) -> Metric:
    """Add a metric (names are unique)."""
    if metric.name in _METRICS:
        raise ValueError(f"metric {metric.name!r} is already registered")
    _METRICS[metric.name] = metric
    return metric


def get_metric(name: str) -> Metric:
    """The metric called ``name``; a `KeyError` listing the known names otherwise."""
    try:
        return _METRICS[name]
    except KeyError:
        raise KeyError(f"unknown metric {name!r}; known: {', '.join(_METRICS)}") from None


def find_metric(name: str) -> Metric | None:
    """The metric called ``name``, or None (a column that is no metric, e.g. ``fps``)."""
    return _METRICS.get(name)


def metric_names() -> list[str]:
    """Registered metric names, built-ins first, in registration order."""
    return list(_METRICS)
