"""Warnings that catch a ruined run (`olatbench.bench.health`): the Gaussian count collapsing below
10 % of its initial count, the training PSNR staying below an image of the background alone; said in
the job's log, its warnings.txt and `olatbench status`, with the likely cause."""

from __future__ import annotations

import json

import numpy as np
import pytest
import test_runner_support as support
from click.testing import CliRunner
from skimage.metrics import peak_signal_noise_ratio

from olatbench.bench.execute import run_job
from olatbench.bench.health import RunHealth, background_psnr, read_warnings, record_warnings
from olatbench.bench.plan import make_plan
from olatbench.cli import main
from olatbench.metrics.decibels import psnr_from_mse


def test_background_psnr_in_closed_form():
    images = np.full((3, 4, 5, 3), 0.25, dtype=np.float32)
    assert background_psnr(images, np.zeros(3)) == pytest.approx(-10 * np.log10(0.0625))
    assert background_psnr(images, np.full(3, 0.75)) == pytest.approx(-10 * np.log10(0.25))


def test_the_log_psnr_matches_skimage_and_stays_finite_on_an_exact_match():
    rng = np.random.default_rng(0)
    image, target = rng.random((8, 9, 3)), rng.random((8, 9, 3))
    mse = float(np.mean((image - target) ** 2))
    assert psnr_from_mse(mse) == pytest.approx(
        peak_signal_noise_ratio(target, image, data_range=1.0), rel=1e-12
    )
    assert psnr_from_mse(4 * mse, peak=2.0) == pytest.approx(psnr_from_mse(mse), rel=1e-12)
    assert psnr_from_mse(0.0) == pytest.approx(120.0)  # the floor: a number for the log, not +inf


def test_a_collapsing_count_warns_below_ten_percent_of_the_initial_one():
    health = RunHealth(initial_gaussians=10_000, floor_psnr=None, iterations=200)
    health.observe(100, {"num_gaussians": 1_001.0, "psnr": 20.0})
    assert health.check() == []
    health.observe(120, {"num_gaussians": 627.0, "psnr": 20.0})  # the 3dgs run at 200 steps
    (warning,) = health.check()
    assert warning.startswith(
        "collapse: the Gaussian count collapsed from 10000 to 627 by step 120"
    )
    assert "likely cause" in warning
    # a method without Gaussians is not judged by its count
    assert RunHealth(None, None, 200).check() == []


def test_a_training_psnr_below_the_background_warns_only_in_the_second_half():
    health = RunHealth(initial_gaussians=None, floor_psnr=12.0, iterations=100)
    for step in range(1, 50):
        health.observe(step, {"psnr": 9.0})
    assert health.check() == []  # every run starts below; judged from half the run on
    health.observe(50, {"psnr": 9.0})
    (warning,) = health.check()
    assert (
        warning.startswith("below background: the training PSNR (9.00 dB") and "12.00 dB" in warning
    )
    for step in range(51, 101):
        health.observe(step, {"psnr": 15.0})
    assert health.check() == []  # the last steps' mean is what counts


def test_warnings_are_recorded_once_per_kind(tmp_path):
    assert record_warnings(tmp_path, ["collapse: a", "below background: b"]) == [
        "collapse: a",
        "below background: b",
    ]
    assert record_warnings(tmp_path, ["collapse: c"]) == []
    assert read_warnings(tmp_path) == ["collapse: a", "below background: b"]


def test_a_ruined_run_says_so_in_its_log_and_in_status(tmp_path):
    data = support.write_tiny_data(tmp_path / "data", scenes=("Alpha",))
    out = tmp_path / "runs"
    # the trivial method's loss (and so its reported PSNR) includes its noise: 3.0 keeps it far
    # below the background
    (bad,) = make_plan(
        "trivial",
        support.tiny_suite(scenes=("Alpha",)),
        out,
        data_root=data,
        progress=False,
        overrides={"noise": 3.0},
    )
    assert run_job(bad, progress=False).status == "done"
    (warning,) = read_warnings(bad.folder)
    assert warning.startswith("below background:") and "likely cause" in warning
    log = (tmp_path / bad.folder / "log.txt").read_text()
    assert f"WARNING: {warning}" in log
    (good,) = make_plan(
        "trivial", support.tiny_suite(scenes=("Alpha",)), out, data_root=data, progress=False
    )
    assert run_job(good, progress=False).status == "done"
    assert read_warnings(good.folder) == []
    result = CliRunner().invoke(main, ["status", str(out)])
    assert result.exit_code == 0, result.output
    assert f"WARNING {bad.folder.removeprefix(str(out) + '/')}: {warning}" in result.output
    assert "WARNING: below background" in result.output  # the table's note
    states = json.loads(CliRunner().invoke(main, ["status", str(out), "--json"]).output)
    assert sorted(len(state["warnings"]) for state in states) == [0, 1]
