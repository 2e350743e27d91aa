"""Report figures (matplotlib, Agg backend): comparison grids, SSD-GS decompositions, training curves, written as
PNG, SVG or PDF (`encode`).

Images are float32 (H, W, 3) sRGB in [0, 1]. Error maps show the per-pixel mean absolute error over the three
channels on a fixed scale (0 to ``error_max``, "magma"), so panels are comparable; the colour bar has a column of its
own, so every error map is as large as every render. Each method has one colour in every figure of a report
(`method_colours`): the lines of its training curves and the title of its panels.
"""

from __future__ import annotations

import io
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from olatbench.metrics.psnr import psnr

COMPONENT_TITLES = {"diffuse": "Diffuse", "specular": "Specular", "sss": "SSS", "shadow_coarse": "Coarse shadow",
                    "shadow": "Refined shadow", "rgb": "Final"}
FIGURE_FORMATS = ("png", "svg", "pdf")
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
           "#17becf")  # matplotlib's tab10
EMBED_DPI = 150  # the PNG inside the HTML page
FILE_DPI = 300  # PNG files (SVG and PDF are vector; their images keep their pixels)
LOG_SCALE_KEYS = ("loss", "l1")  # training-curve panels drawn on a log axis


@dataclass
class ComparisonRow:
    """One frame of a comparison grid: its id, ground truth and each method's render (same size)."""

    frame_id: str
    ground_truth: np.ndarray
    predictions: Sequence[tuple[str, np.ndarray]]


def method_colours(labels: Iterable[str]) -> dict[str, str]:
    """One colour per method label, the same whatever figure or panel shows it: labels are sorted and take the
    palette in turn (cycling past ten methods)."""
    return {label: PALETTE[index % len(PALETTE)] for index, label in enumerate(sorted(set(labels)))}


def encode(figure: Figure, fmt: str = "png", dpi: int = EMBED_DPI) -> bytes:
    """The figure as ``fmt`` (one of `FIGURE_FORMATS`) bytes; the figure stays open."""
    if fmt not in FIGURE_FORMATS:
        raise ValueError(f"unknown figure format {fmt!r}; choose one of {', '.join(FIGURE_FORMATS)}")
    buffer = io.BytesIO()
    metadata = {"Date": None} if fmt == "svg" else {"CreationDate": None} if fmt == "pdf" else {}
    figure.savefig(buffer, format=fmt, dpi=dpi, bbox_inches="tight", metadata=metadata)
    return buffer.getvalue()


def close(figure: Figure) -> None:
    """Free a figure made here."""
    plt.close(figure)


def error_map(prediction: np.ndarray, ground_truth: np.ndarray) -> np.ndarray:
    """Mean absolute error over channels, (H, W); shapes must match."""
    if prediction.shape != ground_truth.shape:
        raise ValueError(f"render {prediction.shape} and ground truth {ground_truth.shape} differ in shape")
    return np.abs(prediction.astype(np.float32) - ground_truth.astype(np.float32)).mean(axis=-1)


def _show(axis, image: np.ndarray, title: str, colour: str | None = None, **kwargs):
    shown = axis.imshow(np.clip(image, 0.0, 1.0) if image.ndim == 3 else image, **kwargs)
    axis.set_title(title, fontsize=8, **({"color": colour} if colour else {}))
    axis.set_xticks([])
    axis.set_yticks([])
    return shown


def comparison_figure(rows: Sequence[ComparisonRow], error_max: float = 0.2, panel_inches: float = 2.0,
                      colours: Mapping[str, str] | None = None) -> Figure:
    """Ground truth | each method (with its PSNR) | each method's error map | the error scale, one row per frame.
    Every image panel has the same size; method titles take the method's colour (``colours``, default
    `method_colours` of the labels)."""
    if not rows:
        raise ValueError("comparison_grid needs at least one frame")
    labels = [label for label, _ in rows[0].predictions]
    colours = dict(colours) if colours is not None else method_colours(labels)
    methods = len(labels)
    height, width = rows[0].ground_truth.shape[:2]
    panel = (panel_inches, panel_inches * height / width)
    bar = 0.08  # the colour bar's column, as a fraction of a panel's width
    figure, axes = plt.subplots(len(rows), 2 + 2 * methods, squeeze=False,
                                figsize=(panel[0] * (1 + 2 * methods + bar), (panel[1] + 0.35) * len(rows)),
                                gridspec_kw={"width_ratios": [1.0] * (1 + 2 * methods) + [bar]})
    for r, row in enumerate(rows):
        _show(axes[r, 0], row.ground_truth, f"GT {row.frame_id}")
        for m, (label, prediction) in enumerate(row.predictions):
            value = psnr(np.clip(prediction, 0, 1), row.ground_truth)
            colour = colours.get(label)
            _show(axes[r, 1 + m], prediction, f"{label} ({value:.2f} dB)", colour)
            shown = _show(axes[r, 1 + methods + m], error_map(prediction, row.ground_truth), f"|error| {label}",
                          colour, cmap="magma", vmin=0.0, vmax=error_max)
        figure.colorbar(shown, cax=axes[r, -1])
        axes[r, -1].tick_params(labelsize=7)
    return figure


def decomposition_figure(components: Mapping[str, np.ndarray], title: str = "", panel_inches: float = 2.0) -> Figure:
    """SSD-GS components side by side in the given order (diffuse, specular, SSS, shadows, final)."""
    if not components:
        raise ValueError("decomposition_figure needs at least one component")
    figure, axes = plt.subplots(1, len(components), figsize=(panel_inches * len(components), panel_inches * 1.1),
                                squeeze=False)
    for axis, (name, image) in zip(axes[0], components.items(), strict=True):
        _show(axis, image, COMPONENT_TITLES.get(name, name))
    if title:
        figure.suptitle(title, fontsize=9)
    return figure


def _series(entries: Sequence[Mapping[str, float]], key: str, positive: bool) -> tuple[list[float], list[float], int]:
    """(steps, values, count left out): finite values of ``key``; with ``positive``, only those above zero (a log
    axis cannot show zero, and matplotlib would stretch it to 1e-300 to try)."""
    points = [(e["step"], e[key]) for e in entries if key in e and np.isfinite(e[key])]
    kept = [(step, value) for step, value in points if value > 0] if positive else points
    steps, values = (list(column) for column in zip(*kept, strict=True)) if kept else ([], [])
    return steps, values, len(points) - len(kept)


def training_curves_figure(logs: Mapping[str, Sequence[Mapping[str, float]]], keys: Sequence[str] = ("loss", "psnr"),
                           colours: Mapping[str, str] | None = None) -> Figure:
    """One panel per key (loss, PSNR, ...) against step, one line per run in its colour (``colours``, default
    `method_colours` of the runs), a legend on every panel; loss and L1 on a log axis, where values ≤ 0 are left out
    and the legend says how many."""
    colours = dict(colours) if colours is not None else method_colours(logs)
    figure, axes = plt.subplots(1, len(keys), figsize=(4.5 * len(keys), 3.2), squeeze=False)
    for axis, key in zip(axes[0], keys, strict=True):
        logarithmic = key in LOG_SCALE_KEYS
        for label, entries in logs.items():
            steps, values, dropped = _series(entries, key, positive=logarithmic)
            if steps or dropped:  # a run whose values are all ≤ 0 keeps its legend entry, saying so
                note = f" ({dropped} value(s) ≤ 0 not drawn)" if dropped else ""
                axis.plot(steps, values, label=label + note, linewidth=1.0, color=colours.get(label))
        axis.set_xlabel("step")
        axis.set_ylabel(key)
        if logarithmic and axis.lines:
            axis.set_yscale("log")
        axis.grid(alpha=0.3)
        if axis.lines:
            axis.legend(fontsize=7)
    return figure


__all__ = ["FIGURE_FORMATS", "ComparisonRow", "close", "comparison_figure", "decomposition_figure", "encode",
           "error_map", "method_colours", "training_curves_figure"]
