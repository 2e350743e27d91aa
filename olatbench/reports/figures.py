"""Report figures as PNG bytes (matplotlib, Agg backend): comparison grids, SSD-GS decompositions,
training curves.

Images are float32 (H, W, 3) sRGB in [0, 1]. Error maps show the per-pixel mean absolute error
over the three channels on a fixed scale (0 to ``error_max``, "magma"), so panels are comparable.
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from olatbench.metrics.psnr import psnr

COMPONENT_TITLES = {"diffuse": "Diffuse", "specular": "Specular", "sss": "SSS", "shadow_coarse": "Coarse shadow",
                    "shadow": "Refined shadow", "rgb": "Final"}


@dataclass
class ComparisonRow:
    """One frame of a comparison grid: its id, ground truth and each method's render (same size)."""

    frame_id: str
    ground_truth: np.ndarray
    predictions: Sequence[tuple[str, np.ndarray]]


def error_map(prediction: np.ndarray, ground_truth: np.ndarray) -> np.ndarray:
    """Mean absolute error over channels, (H, W); shapes must match."""
    if prediction.shape != ground_truth.shape:
        raise ValueError(f"render {prediction.shape} and ground truth {ground_truth.shape} differ in shape")
    return np.abs(prediction.astype(np.float32) - ground_truth.astype(np.float32)).mean(axis=-1)


def _png(figure) -> bytes:
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100, bbox_inches="tight")
    plt.close(figure)
    return buffer.getvalue()


def _show(axis, image: np.ndarray, title: str, **kwargs):
    shown = axis.imshow(np.clip(image, 0.0, 1.0) if image.ndim == 3 else image, **kwargs)
    axis.set_title(title, fontsize=8)
    axis.set_xticks([])
    axis.set_yticks([])
    return shown


def comparison_grid(rows: Sequence[ComparisonRow], error_max: float = 0.2, panel_inches: float = 2.0) -> bytes:
    """Ground truth | each method (with its PSNR) | each method's error map, one row per frame."""
    if not rows:
        raise ValueError("comparison_grid needs at least one frame")
    methods = len(rows[0].predictions)
    columns = 1 + 2 * methods
    figure, axes = plt.subplots(len(rows), columns, figsize=(panel_inches * columns, panel_inches * len(rows)),
                                squeeze=False)
    for r, row in enumerate(rows):
        _show(axes[r, 0], row.ground_truth, f"GT {row.frame_id}")
        for m, (label, prediction) in enumerate(row.predictions):
            value = psnr(np.clip(prediction, 0, 1), row.ground_truth)
            _show(axes[r, 1 + m], prediction, f"{label} ({value:.2f} dB)")
            shown = _show(axes[r, 1 + methods + m], error_map(prediction, row.ground_truth), f"|error| {label}",
                          cmap="magma", vmin=0.0, vmax=error_max)
        figure.colorbar(shown, ax=axes[r, -1], fraction=0.046, pad=0.04)
    return _png(figure)


def decomposition_figure(components: Mapping[str, np.ndarray], title: str = "", panel_inches: float = 2.0) -> bytes:
    """SSD-GS components side by side in the given order (diffuse, specular, SSS, shadows, final)."""
    if not components:
        raise ValueError("decomposition_figure needs at least one component")
    figure, axes = plt.subplots(1, len(components), figsize=(panel_inches * len(components), panel_inches * 1.1),
                                squeeze=False)
    for axis, (name, image) in zip(axes[0], components.items(), strict=True):
        _show(axis, image, COMPONENT_TITLES.get(name, name))
    if title:
        figure.suptitle(title, fontsize=9)
    return _png(figure)


def training_curves(logs: Mapping[str, Sequence[Mapping[str, float]]], keys: Sequence[str] = ("loss", "psnr")) -> bytes:
    """One panel per key (loss, PSNR, ...) against step, one line per run; loss on a log scale."""
    figure, axes = plt.subplots(1, len(keys), figsize=(4.5 * len(keys), 3.2), squeeze=False)
    for axis, key in zip(axes[0], keys, strict=True):
        for label, entries in logs.items():
            points = [(e["step"], e[key]) for e in entries if key in e and np.isfinite(e[key])]
            if points:
                steps, values = zip(*points, strict=True)
                axis.plot(steps, values, label=label, linewidth=1.0)
        axis.set_xlabel("step")
        axis.set_ylabel(key)
        if key == "loss":
            axis.set_yscale("log")
        axis.grid(alpha=0.3)
    handles, _labels = axes[0, 0].get_legend_handles_labels()
    if handles:
        axes[0, -1].legend(fontsize=7)
    return _png(figure)
