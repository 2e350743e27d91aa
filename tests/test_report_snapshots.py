"""Markdown and HTML snapshots of a small report, and the figures embedded in the HTML page.

Update the snapshots after an intended change with
``OLATBENCH_UPDATE_SNAPSHOTS=1 pytest tests/test_report_snapshots.py`` and review the diff.
"""

from __future__ import annotations

import base64
import json
import os
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner
from datasets_trees import write_nrhints_tree
from test_report_runs import make_tiny_runs, metric_values, write_run

from olatbench.cli import main
from olatbench.datasets import load_scene
from olatbench.datasets.images import write_image
from olatbench.reports.collect import collect
from olatbench.reports.figures import (
    ComparisonRow,
    comparison_figure,
    encode,
    error_map,
    training_curves_figure,
)
from olatbench.reports.gallery import report_figures
from olatbench.reports.html import to_html
from olatbench.reports.ranking import rank_table
from olatbench.reports.runs_tables import scene_table
from olatbench.reports.text import to_markdown

SNAPSHOTS = Path(__file__).parent / "snapshots"


def check_snapshot(name: str, text: str) -> None:
    path = SNAPSHOTS / name
    if os.environ.get("OLATBENCH_UPDATE_SNAPSHOTS"):
        path.write_text(text, encoding="utf-8")
    assert path.is_file(), f"{path} missing; create it with OLATBENCH_UPDATE_SNAPSHOTS=1"
    assert text == path.read_text(encoding="utf-8")


@pytest.fixture()
def small_table(tmp_path):
    frame = collect(make_tiny_runs(tmp_path / "runs"))
    return rank_table(scene_table(frame, metrics=["psnr", "lpips"], splits=["test"], average=True))


def test_markdown_snapshot(small_table):
    check_snapshot("report_small.md", to_markdown(small_table))


def test_html_snapshot(small_table):
    check_snapshot("report_small.html", to_html([small_table]))


def _png_from_data_uri(page: str) -> list[np.ndarray]:
    images = []
    for data in re.findall(r'src="data:image/png;base64,([^"]+)"', page):
        raw = base64.b64decode(data)
        assert raw[:8] == b"\x89PNG\r\n\x1a\n"
        images.append(cv2.imdecode(np.frombuffer(raw, np.uint8), cv2.IMREAD_COLOR))
    return images


def test_error_map_matches_brute_force():
    rng = np.random.default_rng(0)
    a, b = rng.random((4, 5, 3), dtype=np.float32), rng.random((4, 5, 3), dtype=np.float32)
    expected = np.array(
        [
            [sum(abs(a[y, x, c] - b[y, x, c]) for c in range(3)) / 3 for x in range(5)]
            for y in range(4)
        ]
    )
    np.testing.assert_allclose(error_map(a, b), expected, rtol=1e-6)
    with pytest.raises(ValueError, match="differ in shape"):
        error_map(a, b[:2])


def test_figures_are_pngs():
    gt = np.full((12, 16, 3), 0.5, np.float32)
    grid = encode(comparison_figure([ComparisonRow("f0", gt, [("a", gt * 0.9), ("b", gt)])]))
    image = cv2.imdecode(np.frombuffer(grid, np.uint8), cv2.IMREAD_COLOR)
    # GT and 2 renders side by side, error maps below
    assert image is not None and image.shape[1] > image.shape[0]
    curves = encode(
        training_curves_figure(
            {
                "run": [
                    {"step": 1, "loss": 0.5, "psnr": 20.0},
                    {"step": 2, "loss": 0.2, "psnr": 24.0},
                ]
            }
        )
    )
    assert curves[:4] == b"\x89PNG"


def _job_folder(
    root: Path, scene_root: Path, method: str, variant: str, seed: int, brightness: float
) -> Path:
    """A finished job folder: results.json, job.json, renders, components and a training log."""
    results = write_run(root, method, variant, "nrhints", "Toy", seed, metric_values(30.0))
    folder = results.parent
    job = {
        "id": f"{method}{seed}",
        "method": method,
        "variant": variant,
        "suite": "nrhints",
        "scene": "Toy",
        "seed": seed,
        "config": {"iterations": 2},
        "scene_path": str(scene_root),
        "scene_format": "nrhints",
        "colourspace": "srgb",
        "resolution": None,
        "train_split": "train",
        "test_split": "test",
    }
    (folder / "job.json").write_text(json.dumps(job))
    scene = load_scene(scene_root)
    for frame in scene.split("test"):
        rgb = frame.load(colourspace="srgb", background="official").rgb
        write_image(
            folder / "renders" / "test" / f"{frame.frame_id}.png", np.clip(rgb * brightness, 0, 1)
        )
        for name in ("diffuse", "shadow"):
            write_image(
                folder / "components" / "test" / name / f"{frame.frame_id}.png", rgb[..., :1]
            )
    (folder / "train_log.jsonl").write_text(
        "".join(
            json.dumps({"step": s, "loss": 1.0 / s, "psnr": 20.0 + s}) + "\n" for s in range(1, 4)
        )
    )
    return folder


def toy_runs(tmp_path: Path) -> Path:
    """A run folder with an SSD-GS and a GS³ job on a tiny NRHints scene
    (renders, components, curves)."""
    scene_root = tmp_path / "data" / "Toy"
    write_nrhints_tree(scene_root, n_train=3, n_test=2, size=(16, 12))
    runs = tmp_path / "runs"
    _job_folder(runs, scene_root, "ssdgs", "nrhints", 0, 1.0)
    _job_folder(runs, scene_root, "gs3", "default", 0, 0.8)
    return runs


def test_html_report_embeds_comparison_decomposition_and_curves(tmp_path):
    runs = toy_runs(tmp_path)
    figures, notes = report_figures(collect(runs))
    titles = [figure.title for figure in figures]
    assert titles[0] == "nrhints/Toy: ground truth, renders and error maps"
    assert (
        sum("decomposition" in t for t in titles) == 2
        and titles[-1] == "nrhints/Toy: training curves"
    )
    assert notes == []
    out = tmp_path / "report.html"
    result = CliRunner().invoke(main, ["report", str(runs), "--suite", "nrhints", "-o", str(out)])
    assert result.exit_code == 0, result.output
    page = out.read_text()
    assert len(_png_from_data_uri(page)) == 4
    assert "<script" not in page and "http" not in page.split("<body>")[1]  # self-contained


def test_missing_scene_data_skips_a_figure_with_a_note(tmp_path):
    scene_root = tmp_path / "data" / "Toy"
    write_nrhints_tree(scene_root, n_train=3, n_test=1, size=(16, 12))
    runs = tmp_path / "runs"
    _job_folder(runs, scene_root, "ssdgs", "nrhints", 0, 1.0)
    (scene_root / "transforms_test.json").rename(scene_root / "moved.json")
    figures, notes = report_figures(collect(runs))
    assert any("comparison grid skipped" in note for note in notes)
    assert any("training curves" in figure.title for figure in figures)
