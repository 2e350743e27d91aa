"""Report figures (matplotlib, Agg backend): comparison grids, SSD-GS decompositions, training
curves, written as PNG, SVG or PDF (`encode`).

Images are float32 (H, W, 3) sRGB in [0, 1]. Error maps show the per-pixel mean absolute error over
the three channels on a fixed scale (0 to ``error_max``, "magma"), so panels are comparable; the
colour bar has a column of its own, so every error map is as large as every render. Each method has
one colour and one short key (A, B, …) in every figure of a report
(`method_colours`, `method_keys`): panels are titled by the key, which a key legend under the figure
spells out as the method's full label (wrapped to the figure's width), so however long the labels
and however many methods, no two titles overlap.
"""

from __future__ import annotations

import io
import string
import textwrap
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from olatbench.metrics.psnr import psnr

COMPONENT_TITLES = {
    "diffuse": "Diffuse",
    "specular": "Specular",
    "sss": "SSS",
    "shadow_coarse": "Coarse shadow",
    "shadow": "Refined shadow",
    "rgb": "Final",
}
FIGURE_FORMATS = ("png", "svg", "pdf")
PALETTE = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
)  # matplotlib's tab10
EMBED_DPI = 150  # the PNG inside the HTML page
FILE_DPI = 300  # PNG files (SVG and PDF are vector; their images keep their pixels)
LOG_SCALE_KEYS = ("loss", "l1")  # training-curve panels drawn on a log axis
KEY_FONT_SIZE = 9  # points: the key legend under a figure


@dataclass
class ComparisonRow:
    """One frame of a comparison grid: its id, ground truth and each method's render (same size)."""

    frame_id: str
    ground_truth: np.ndarray
    predictions: Sequence[tuple[str, np.ndarray]]


def method_colours(labels: Iterable[str]) -> dict[str, str]:
    """One colour per method label, the same whatever figure or panel shows it: labels are sorted
    and take the palette in turn (cycling past ten methods)."""
    return {label: PALETTE[index % len(PALETTE)] for index, label in enumerate(sorted(set(labels)))}


def method_keys(labels: Iterable[str]) -> dict[str, str]:
    """One short key per method label, in the order of `method_colours` (sorted labels): A, B, …, Z,
    AA, AB, …"""
    letters = string.ascii_uppercase
    keys = {}
    for index, label in enumerate(sorted(set(labels))):
        key = ""
        index += 1
        while index:
            index, rest = divmod(index - 1, len(letters))
            key = letters[rest] + key
        keys[label] = key
    return keys


def key_legend(
    figure: Figure, keys: Mapping[str, str], colours: Mapping[str, str], width_inches: float
) -> None:
    """Spell out the keys below the figure's panels, one line per method in its colour
    (``A  full label``), each label wrapped to ``width_inches`` (saved with
    ``bbox_inches="tight"``, which takes the legend in)."""
    characters = max(20, int(width_inches * 72 / (KEY_FONT_SIZE * 0.6)))  # ~0.6 em per character
    handles = [Patch(color=colours.get(label, "#000000")) for label in keys]
    texts = [
        f"{key}: " + "\n    ".join(textwrap.wrap(label, characters - 4) or [""])
        for label, key in keys.items()
    ]
    figure.legend(
        handles,
        texts,
        loc="upper left",
        bbox_to_anchor=(figure.subplotpars.left, 0.0),
        ncols=1,
        fontsize=KEY_FONT_SIZE,
        frameon=False,
        handlelength=1.0,
        borderaxespad=0.0,
        title="Key",
        title_fontsize=KEY_FONT_SIZE,
        alignment="left",
    )


def encode(figure: Figure, fmt: str = "png", dpi: int = EMBED_DPI) -> bytes:
    """The figure as ``fmt`` (one of `FIGURE_FORMATS`) bytes; the figure stays open."""
    if fmt not in FIGURE_FORMATS:
        raise ValueError(
            f"unknown figure format {fmt!r}; choose one of {', '.join(FIGURE_FORMATS)}"
        )
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
        raise ValueError(
            f"render {prediction.shape} and ground truth {ground_truth.shape} differ in shape"
        )
    return np.abs(prediction.astype(np.float32) - ground_truth.astype(np.float32)).mean(axis=-1)


def _show(axis, image: np.ndarray, title: str, colour: str | None = None, **kwargs):
    shown = axis.imshow(np.clip(image, 0.0, 1.0) if image.ndim == 3 else image, **kwargs)
    axis.set_title(title, fontsize=8, **({"color": colour} if colour else {}))
    axis.set_xticks([])
    axis.set_yticks([])
    return shown


def comparison_figure(
    rows: Sequence[ComparisonRow],
    error_max: float = 0.2,
    panel_inches: float = 2.0,
    colours: Mapping[str, str] | None = None,
    keys: Mapping[str, str] | None = None,
) -> Figure:
    """Per frame two rows: ground truth | each method's render (its key and PSNR), then under each
    render that method's error map, with the error scale at the end; the key legend under the grid.
    Every image panel has the same size; a method's key and legend line take its colour
    (``colours``, default `method_colours`; ``keys``, default `method_keys` of the labels)."""
    if not rows:
        raise ValueError("comparison_grid needs at least one frame")
    labels = [label for label, _ in rows[0].predictions]
    colours = dict(colours) if colours is not None else method_colours(labels)
    keys = dict(keys) if keys is not None else method_keys(labels)
    methods = len(labels)
    height, width = rows[0].ground_truth.shape[:2]
    panel = (panel_inches, panel_inches * height / width)
    bar = 0.08  # the colour bar's column, as a fraction of a panel's width
    figure_width = panel[0] * (1 + methods + bar)
    figure, axes = plt.subplots(
        2 * len(rows),
        2 + methods,
        squeeze=False,
        figsize=(figure_width, (panel[1] + 0.35) * 2 * len(rows)),
        gridspec_kw={"width_ratios": [1.0] * (1 + methods) + [bar]},
    )
    for r, row in enumerate(rows):
        renders, errors = axes[2 * r], axes[2 * r + 1]
        _show(renders[0], row.ground_truth, f"GT {row.frame_id}")
        figure.delaxes(errors[0])  # nothing under the ground truth
        figure.delaxes(renders[-1])  # the scale belongs to the error maps
        for m, (label, prediction) in enumerate(row.predictions):
            value = psnr(np.clip(prediction, 0, 1), row.ground_truth)
            colour = colours.get(label)
            _show(renders[1 + m], prediction, f"{keys[label]}: {value:.2f} dB", colour)
            shown = _show(
                errors[1 + m],
                error_map(prediction, row.ground_truth),
                f"|error| {keys[label]}",
                colour,
                cmap="magma",
                vmin=0.0,
                vmax=error_max,
            )
        figure.colorbar(shown, cax=errors[-1])
        errors[-1].tick_params(labelsize=7)
    key_legend(
        figure,
        {label: keys[label] for label in sorted(labels, key=keys.__getitem__)},
        colours,
        figure_width,
    )
    return figure


def decomposition_figure(
    components: Mapping[str, np.ndarray], title: str = "", panel_inches: float = 2.0
) -> Figure:
    """SSD-GS components side by side in the given order (diffuse, specular, SSS, shadows,
    final)."""
    if not components:
        raise ValueError("decomposition_figure needs at least one component")
    figure, axes = plt.subplots(
        1,
        len(components),
        figsize=(panel_inches * len(components), panel_inches * 1.1),
        squeeze=False,
    )
    for axis, (name, image) in zip(axes[0], components.items(), strict=True):
        _show(axis, image, COMPONENT_TITLES.get(name, name))
    if title:
        figure.suptitle(title, fontsize=9)
    return figure


def _series(
    entries: Sequence[Mapping[str, float]], key: str, positive: bool
) -> tuple[list[float], list[float], int]:
    """(steps, values, count left out): finite values of ``key``; with ``positive``, only those
    above zero (a log axis cannot show zero, and matplotlib would stretch it to 1e-300 to try)."""
    points = [(e["step"], e[key]) for e in entries if key in e and np.isfinite(e[key])]
    kept = [(step, value) for step, value in points if value > 0] if positive else points
    steps, values = (list(column) for column in zip(*kept, strict=True)) if kept else ([], [])
    return steps, values, len(points) - len(kept)


def training_curves_figure(
    logs: Mapping[str, Sequence[Mapping[str, float]]],
    keys: Sequence[str] = ("loss", "psnr"),
    colours: Mapping[str, str] | None = None,
    method_key: Mapping[str, str] | None = None,
) -> Figure:
    """One panel per key (loss, PSNR, ...) against step, one line per run in its colour
    (``colours``, default `method_colours` of the runs), named by its short key (``method_key``,
    default `method_keys`) in a legend on every panel and spelt out in the key legend under the
    figure; loss and L1 on a log axis, where values ≤ 0 are left out and the legend says how
    many."""
    colours = dict(colours) if colours is not None else method_colours(logs)
    method_key = dict(method_key) if method_key is not None else method_keys(logs)
    width = 4.5 * len(keys)
    figure, axes = plt.subplots(1, len(keys), figsize=(width, 3.2), squeeze=False)
    for axis, key in zip(axes[0], keys, strict=True):
        logarithmic = key in LOG_SCALE_KEYS
        for label, entries in logs.items():
            steps, values, dropped = _series(entries, key, positive=logarithmic)
            if steps or dropped:  # a run whose values are all ≤ 0 keeps its legend entry, saying so
                note = f" ({dropped} value(s) ≤ 0 not drawn)" if dropped else ""
                axis.plot(
                    steps,
                    values,
                    label=method_key[label] + note,
                    linewidth=1.0,
                    color=colours.get(label),
                )
        axis.set_xlabel("step")
        axis.set_ylabel(key)
        if logarithmic and axis.lines:
            axis.set_yscale("log")
        axis.grid(alpha=0.3)
        if axis.lines:
            axis.legend(fontsize=7)
    key_legend(
        figure,
        {label: method_key[label] for label in sorted(logs, key=method_key.__getitem__)},
        colours,
        width,
    )
    return figure


__all__ = [
    "FIGURE_FORMATS",
    "ComparisonRow",
    "close",
    "comparison_figure",
    "decomposition_figure",
    "encode",
    "error_map",
    "key_legend",
    "method_colours",
    "method_keys",
    "training_curves_figure",
]
