"""Slow: train SSD-GS briefly with the real runner on a tiny NRHints scene, then report and render
from its folder."""

from __future__ import annotations

import base64
import re

import pytest
from click.testing import CliRunner
from datasets_trees import write_nrhints_tree

from olatbench.cli import main


@pytest.mark.slow
def test_run_then_report_html_and_render(tmp_path):
    write_nrhints_tree(tmp_path / "data" / "Cat", n_train=6, n_test=2, size=(32, 24))
    runner = CliRunner()
    run = runner.invoke(
        main,
        [
            "run",
            "-m",
            "ssdgs",
            "-s",
            "nrhints",
            "--scenes",
            "Cat",
            "--variant",
            "mini",
            "--data-root",
            str(tmp_path / "data"),
            "--iterations",
            "20",
            "--save-components",
            "-o",
            str(tmp_path / "runs"),
        ],
    )
    assert run.exit_code == 0, run.output
    job = tmp_path / "runs" / "nrhints" / "ssdgs" / "mini~iterations=20" / "Cat" / "seed0"
    assert (job / "results.json").is_file()

    out = tmp_path / "report.html"
    report = runner.invoke(
        main,
        ["report", str(tmp_path / "runs"), "--suite", "nrhints", "--published", "-o", str(out)],
    )
    assert report.exit_code == 0, report.output
    page = out.read_text()
    images = re.findall(r'src="data:image/png;base64,([^"]+)"', page)
    assert len(images) >= 3  # comparison grid, decomposition, training curves
    assert all(base64.b64decode(data)[:4] == b"\x89PNG" for data in images)
    assert "Ours (paper)" in page and "27.6844" in page

    render = runner.invoke(
        main, ["render", str(job), "--sweep", "paper", "--frames", "4", "-o", str(tmp_path / "v")]
    )
    assert render.exit_code == 0, render.output
    assert len(list((tmp_path / "v" / "paper_frames").glob("*.png"))) == 4
    assert (tmp_path / "v" / "paper.mp4").stat().st_size > 0
