"""Report figures a paper can use (#37): one colour per method in every panel and figure, legends, a
log axis that a zero loss does not stretch, error maps all of one size, and figure files
(PNG, SVG, PDF) beside the HTML page."""

from __future__ import annotations

import html
import re

import numpy as np
import pytest
from click.testing import CliRunner
from matplotlib.colors import to_hex
from test_report_snapshots import toy_runs

from olatbench.cli import main
from olatbench.reports.collect import collect
from olatbench.reports.figures import (
    ComparisonRow,
    close,
    comparison_figure,
    method_keys,
    training_curves_figure,
)
from olatbench.reports.gallery import report_figures


def _log(steps, loss, psnr=None):
    return [{"step": s, "loss": loss(s), **({"psnr": psnr(s)} if psnr else {})} for s in steps]


def _line_colours(axis, keys: dict[str, str]) -> dict[str, str]:
    """Label -> colour of each line of a panel (lines are named by their short key)."""
    labels = {key: label for label, key in keys.items()}
    return {
        labels[line.get_label().split(" (")[0]]: to_hex(line.get_color()) for line in axis.lines
    }


def test_a_method_has_one_colour_in_the_loss_and_psnr_panels_and_both_have_legends():
    # "plugin" logs no PSNR: with matplotlib's colour cycle per panel, "ssdgs" took the first colour
    # in the PSNR panel and the second in the loss panel
    logs = {
        "plugin": _log(range(1, 5), lambda s: 0.5),
        "ssdgs": _log(range(1, 5), lambda s: 1 / s, lambda s: 20 + s),
    }
    figure = training_curves_figure(logs)
    keys = method_keys(logs)
    loss, psnr = figure.axes[:2]
    try:
        assert _line_colours(loss, keys)["ssdgs"] == _line_colours(psnr, keys)["ssdgs"]
        assert _line_colours(loss, keys)["plugin"] != _line_colours(loss, keys)["ssdgs"]
        for axis in (loss, psnr):
            legend = axis.get_legend()
            assert legend is not None
            assert {text.get_text().split(" (")[0] for text in legend.get_texts()} == {
                keys[label] for label in _line_colours(axis, keys)
            }
    finally:
        close(figure)


def test_a_zero_loss_does_not_stretch_the_log_axis_and_the_legend_says_so():
    logs = {
        "learning-free": _log(range(1, 5), lambda s: 0.0),
        "ssdgs": _log(range(1, 5), lambda s: 0.1 / s),
    }
    figure = training_curves_figure(logs)
    loss = figure.axes[0]
    try:
        low, high = loss.get_ylim()
        # the data span 0.025 to 0.1
        assert loss.get_yscale() == "log" and low > 1e-3 and high < 1.0
        labels = [text.get_text() for text in loss.get_legend().get_texts()]
        assert f"{method_keys(logs)['learning-free']} (4 value(s) ≤ 0 not drawn)" in labels
    finally:
        close(figure)


def test_every_panel_of_the_comparison_grid_has_one_size():
    truth = np.full((12, 16, 3), 0.5, np.float32)
    rows = [
        ComparisonRow(f"f{i}", truth, [("a", truth * 0.9), ("b", truth * 0.7), ("c", truth)])
        for i in range(2)
    ]
    figure = comparison_figure(rows)
    try:
        figure.canvas.draw()
        images = [axis for axis in figure.axes if axis.images]
        assert len(images) == 2 * 7
        sizes = {
            (round(box.width), round(box.height))
            for box in (axis.get_window_extent() for axis in images)
        }
        # the colour bar used to shrink the last error map of each row
        assert len(sizes) == 1, sizes
        bars = [axis for axis in figure.axes if not axis.images]
        assert len(bars) == 2 and all(
            bar.get_window_extent().width < 0.2 * next(iter(sizes))[0] for bar in bars
        )
    finally:
        close(figure)


def test_method_colours_agree_across_the_figures_of_a_report(tmp_path):
    figures, _ = report_figures(collect(toy_runs(tmp_path)))
    try:
        grid = next(f.figure for f in figures if "error maps" in f.title)
        curves = next(f.figure for f in figures if "training curves" in f.title)
        keys = method_keys(["ssdgs/nrhints", "gs3"])  # the labels of the toy runs' experiments
        labels = {key: label for label, key in keys.items()}
        titles = {
            labels[axis.get_title().split(":")[0]]: to_hex(axis.title.get_color())
            for axis in grid.axes
            if axis.images and not axis.get_title().startswith(("GT", "|error|"))
        }
        assert set(titles) == {"ssdgs/nrhints", "gs3"}
        for axis in curves.axes:
            assert _line_colours(axis, keys) == titles
        assert len(set(titles.values())) == 2
    finally:
        for figure in figures:
            figure.close()


def _visible_text(page: str) -> str:
    body = re.sub(r"<(style|script)[^>]*>.*?</\1>", "", page, flags=re.S)
    return html.unescape(re.sub(r"<[^>]+>", " ", body))


@pytest.mark.parametrize(
    ("fmt", "magic"), [("pdf", b"%PDF"), ("svg", b"<?xml"), ("png", b"\x89PNG")]
)
def test_figures_are_written_as_files_beside_the_page_and_linked(tmp_path, fmt, magic):
    runs = toy_runs(tmp_path)
    page = tmp_path / "out" / "report.html"
    result = CliRunner().invoke(
        main, ["report", str(runs), "--suite", "nrhints", "-o", str(page), "--figures", fmt]
    )
    assert result.exit_code == 0, result.output
    files = sorted((tmp_path / "out" / "report_figures").iterdir())
    assert [path.name for path in files] == [
        f"01-nrhints-toy-ground-truth-renders-and-error-maps.{fmt}",
        f"02-gs3-toy-seed0-decomposition.{fmt}",
        f"03-ssdgs-nrhints-toy-seed0-decomposition.{fmt}",
        f"04-nrhints-toy-training-curves.{fmt}",
    ]
    assert all(path.read_bytes().startswith(magic) for path in files)
    text = page.read_text()
    assert text.count('src="data:image/png;base64,') == 4  # the page still embeds every figure
    for path in files:
        assert f'href="report_figures/{path.name}"' in text


def test_figure_files_need_an_html_page(tmp_path):
    runs = toy_runs(tmp_path)
    result = CliRunner().invoke(main, ["report", str(runs), "--figures", "pdf"])
    assert result.exit_code == 2 and "-o report.html" in result.output


def test_the_latex_label_is_an_anchor_not_text(tmp_path):
    runs = toy_runs(tmp_path)
    page = tmp_path / "report.html"
    result = CliRunner().invoke(
        main, ["report", str(runs), "--suite", "nrhints", "-o", str(page), "--figures", "none"]
    )
    assert result.exit_code == 0, result.output
    text = page.read_text()
    assert 'id="tab:nrhints"' in text and "tab:nrhints" not in _visible_text(text)
    assert "<img" not in text


def test_an_embedded_figure_shows_at_the_size_it_was_drawn_for():
    import cv2

    from olatbench.reports.figures import EMBED_DPI, encode
    from olatbench.reports.html import figure_html, png_css_width

    figure = training_curves_figure({"run": _log(range(1, 5), lambda s: 1 / s, lambda s: 20 + s)})
    try:
        data = encode(figure, "png", EMBED_DPI)
    finally:
        close(figure)
    pixels = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR).shape[1]
    # CSS pixels are 1/96 inch; the PNG stores its resolution in whole pixels per metre
    # (150 dpi: 5905, 149.99 dpi)
    assert abs(png_css_width(data) - pixels * 96 / EMBED_DPI) <= 1
    assert f'width="{png_css_width(data)}"' in figure_html("curves", data)


def test_the_comparison_caption_names_frame_light_and_metric_of_each_panel(tmp_path):
    runs = toy_runs(tmp_path)
    figures, _ = report_figures(collect(runs))
    try:
        grid = next(f for f in figures if "error maps" in f.title)
        assert re.search(
            r"rows 1–2: test frame \S+, lit by a point light at \(-?\d+\.\d\d, -?\d+\.\d\d, "
            r"-?\d+\.\d\d\)",
            grid.caption,
        )
        assert (
            "PSNR in dB" in grid.caption
            and "|render − GT|" in grid.caption
            and "0–0.2" in grid.caption
        )
    finally:
        for figure in figures:
            figure.close()
    page = tmp_path / "report.html"
    assert (
        CliRunner()
        .invoke(main, ["report", str(runs), "--suite", "nrhints", "-o", str(page)])
        .exit_code
        == 0
    )
    assert "lit by a point light at" in _visible_text(page.read_text())
