"""The HTML report opens in a real browser: headless Chromium renders it to a screenshot
(slow; needs Debian's ``chromium``)."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest
from click.testing import CliRunner
from test_report_snapshots import toy_runs
from waiting import BACKSTOP_SECONDS

from olatbench.cli import main
from olatbench.datasets.images import read_image

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"]


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="needs Debian's chromium (apt-get install chromium)")
def test_html_report_renders_tables_and_figures_in_chromium(tmp_path):
    runs = toy_runs(tmp_path)
    page = tmp_path / "report.html"
    result = CliRunner().invoke(main, ["report", str(runs), "--suite", "nrhints", "-o", str(page)])
    assert result.exit_code == 0, result.output

    dom = subprocess.run(
        [CHROMIUM, *FLAGS, "--dump-dom", page.as_uri()],
        capture_output=True,
        text=True,
        timeout=BACKSTOP_SECONDS,
    ).stdout
    assert dom.count("<table") >= 1 and dom.count("<img") == 4
    shot = tmp_path / "shot.png"
    subprocess.run(
        [CHROMIUM, *FLAGS, f"--screenshot={shot}", "--window-size=1400,2400", page.as_uri()],
        capture_output=True,
        timeout=BACKSTOP_SECONDS,
        check=True,
    )
    pixels = read_image(shot)[..., :3]
    ink = np.mean(np.abs(pixels - 1.0).sum(axis=2) > 0.1)  # fraction of non-white pixels
    assert 0.02 < ink < 0.95 and pixels.std() > 0.05
