"""Metrics registered as data (`olatbench.metrics.registry`): a protocol lists metric names and
computes each with the metric's function; the reports title and rank a metric's column from the
registry. A toy metric is added here through the registry alone: no file of the package changes."""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest
from test_report_runs import write_run

from olatbench.bench.results import ResultsError, read_results, write_results
from olatbench.metrics.protocols import Protocol, get_protocol, register_protocol
from olatbench.metrics.registry import (
    Metric,
    MetricBatch,
    get_metric,
    metric_names,
    register_metric,
)
from olatbench.reports.collect import collect
from olatbench.reports.layouts import metric_title
from olatbench.reports.ranking import rank_table
from olatbench.reports.runs_tables import scene_table

TOY = Metric(
    "toy_red_gap",
    "Red gap",
    "min",
    "test_metric_registry:red_gap",
    "mean |pred - gt| of the red channel",
)


def red_gap(batch: MetricBatch, protocol: Protocol) -> list[float]:
    """The toy metric: per image, the mean absolute difference of the red channels."""
    return (batch.pred[:, 0] - batch.gt[:, 0]).abs().flatten(1).mean(1).tolist()


@pytest.fixture(scope="module")
def toy_protocol() -> Protocol:
    if "toy_red_gap" not in metric_names():
        register_metric(TOY)
    if "toy-v1" not in [name for name in _protocol_ids()]:
        register_protocol(
            Protocol(
                id="toy-v1",
                version=1,
                description="PSNR and the red gap",
                reproduces="nothing",
                quantize=None,
                metric_names=("psnr", "toy_red_gap"),
            )
        )
    return get_protocol("toy-v1")


def _protocol_ids() -> list[str]:
    from olatbench.metrics.protocols import protocol_names

    return protocol_names()


def test_a_toy_metric_is_scored_titled_and_ranked_through_the_registry(toy_protocol, tmp_path):
    gt = np.zeros((8, 8, 3), dtype=np.float32)
    pred = gt.copy()
    pred[..., 0] = 0.25
    values = toy_protocol.evaluate(pred, gt)
    assert list(values) == ["psnr", "toy_red_gap"]
    assert values["toy_red_gap"] == pytest.approx(0.25)
    assert values["psnr"] == pytest.approx(10 * np.log10(1 / (0.25**2 / 3)))
    assert toy_protocol.definition()["metrics"] == ["psnr", "toy_red_gap"]
    assert metric_title("toy_red_gap") == "Red gap ↓"
    root = tmp_path / "runs"  # lower is better: the smaller gap ranks first
    # results of olatbench-v1 (write_run's), plus the toy metric
    for method, gap in (("a", 0.3), ("b", 0.1)):
        write_run(
            root,
            method,
            "default",
            "mini",
            "diffuse_shadow",
            0,
            {"test": {"psnr": 30.0, "ssim": 0.9, "lpips": 0.1, "toy_red_gap": gap}},
        )
    table = rank_table(scene_table(collect(root), metrics=["toy_red_gap"], splits=["test"]))
    assert table.blocks[0].title == "Red gap ↓"
    ranks = {row.labels[0]: row.cells[0].rank for row in table.blocks[0].rows}
    assert ranks == {"a": 2, "b": 1}


def test_results_of_a_protocol_without_ssim_and_lpips_are_read(toy_protocol, tmp_path):
    """results.json's check of a finished job's metrics asks its protocol which of psnr, ssim, lpips
    it lists."""
    path = write_run(
        tmp_path / "runs",
        "a",
        "default",
        "mini",
        "diffuse_shadow",
        0,
        {"test": {"psnr": 30.0, "ssim": 0.9, "lpips": 0.1}},
    )
    data = json.loads(path.read_text())
    data["protocol"] = {"id": "toy-v1", "version": 1}
    data["metrics"]["test"]["mean"] = {"psnr": 30.0, "toy_red_gap": 0.2}
    write_results(path, data)
    assert read_results(path)["metrics"]["test"]["mean"] == {"psnr": 30.0, "toy_red_gap": 0.2}
    data["protocol"] = {"id": "olatbench-v1", "version": 1}
    with pytest.raises(ResultsError, match="missing ssim, lpips"):
        write_results(path, data)


def test_a_protocol_listing_an_unregistered_metric_is_refused():
    with pytest.raises(ValueError, match=r"lists unregistered metrics \['nope'\]"):
        register_protocol(
            Protocol(
                id="broken-v1",
                version=1,
                description="",
                reproduces="",
                metric_names=("psnr", "nope"),
            )
        )
    with pytest.raises(KeyError, match="unknown metric 'nope'"):
        get_metric("nope")


def test_the_built_in_metrics_and_protocols_report_what_they_did():
    assert metric_names()[:6] == ["psnr", "ssim", "lpips", "lpips_alex", "lpips_vgg", "flip"]
    assert [metric_title(name) for name in ("psnr", "ssim", "lpips", "lpips_vgg")] == [
        "PSNR ↑",
        "SSIM ↑",
        "LPIPS ↓",
        "LPIPS (VGG) ↓",
    ]
    assert get_protocol("olatbench-v1").metrics == (
        "psnr",
        "ssim",
        "lpips",
        "lpips_alex",
        "lpips_vgg",
    )
    assert get_protocol("ssdgs").metrics == ("psnr", "ssim", "lpips")
    definition = get_protocol("olatbench-v1").definition()
    assert "metric_names" not in definition and definition["metrics"][-1] == "lpips_vgg"
    assert json.loads(json.dumps(definition)) == definition


def test_flip_is_reachable_through_its_own_protocol(recwarn):
    """olatbench-v1-flip: olatbench-v1's numbers and LDR-FLIP (None, with a warning, without
    flip-evaluator)."""
    protocol = get_protocol("olatbench-v1-flip")
    assert (protocol.version, protocol.metrics[-1]) == (1, "flip")
    assert "flip" not in get_protocol("olatbench-v1").metrics
    rng = np.random.default_rng(3)
    gt = rng.random((40, 40, 3), dtype=np.float32)
    pred = np.clip(gt + 0.05, 0.0, 1.0)
    reference = get_protocol("olatbench-v1").evaluate(pred, gt)
    values = protocol.evaluate(pred, gt)
    # the v1 part is olatbench-v1, to the bit
    assert {key: values[key] for key in reference} == reference
    if importlib.util.find_spec("flip_evaluator") is None:
        assert values["flip"] is None
        assert any("pip install flip-evaluator" in str(warning.message) for warning in recwarn)
    else:
        assert 0.0 < values["flip"] < 1.0 and protocol.evaluate(gt, gt)["flip"] == 0.0
