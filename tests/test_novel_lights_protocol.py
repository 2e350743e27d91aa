"""Scores under novel illumination (#57 item 4): the scale-invariant PSNR, the
``olatbench-v1-novel-lights`` protocol, results.json's ``novel_lights`` block,
``run --evaluate novel-lights`` end to end (a tiny SSD-GS job, fresh and finished) and the report's
table."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest
import test_runner_support as support
import torch
from click.testing import CliRunner

from olatbench.bench.relight import restore_relighter
from olatbench.bench.results import ResultsError, read_results, validate_results, write_results
from olatbench.cli import main
from olatbench.datasets import load_scene
from olatbench.datasets.images import read_image, write_image
from olatbench.metrics.protocols import Protocol, get_protocol
from olatbench.metrics.registry import MetricBatch, get_metric
from olatbench.metrics.scale_invariant import least_squares_scale, scale_invariant_psnr

NOVEL = "olatbench-v1-novel-lights"


def _images(
    seed: int = 0, size: tuple[int, int] = (2, 16, 20)
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """A (B, 3, H, W) ground truth in [0, 0.5], a mask (B, 1, H, W) of weights in [0, 1] with empty
    corners."""
    rng = np.random.default_rng(seed)
    batch, height, width = size
    gt = torch.from_numpy(rng.uniform(0.0, 0.5, (batch, 3, height, width)))
    mask = torch.from_numpy(rng.uniform(0.2, 1.0, (batch, 1, height, width)))
    mask[..., :4, :4] = 0.0
    return gt, mask, torch.tensor([0.5, 0.8, 1.7], dtype=torch.float64).view(1, 3, 1, 1)


def test_a_render_that_is_the_ground_truth_times_a_channel_gain_scores_as_the_ground_truth():
    gt, mask, gain = _images()
    exact = scale_invariant_psnr(gt, gt, mask)
    scaled = scale_invariant_psnr(gt * gain, gt, mask)
    # both at the 1e-10 MSE floor
    assert torch.all(exact == 100.0) and torch.allclose(scaled, exact)
    plain = get_metric("psnr").load()(
        MetricBatch((gt * gain).clamp(0, 1), gt, None, "cpu"), get_protocol(NOVEL)
    )
    assert max(plain) < 30.0  # the plain PSNR does see the gain


def test_the_scale_is_the_least_squares_optimum_over_the_mask():
    gt, mask, _ = _images(1)
    pred = torch.from_numpy(np.random.default_rng(2).uniform(0.0, 0.6, gt.shape))
    scale = least_squares_scale(pred, gt, mask)
    # brute force, per image and channel
    grid = torch.linspace(0.2, 2.0, 18001, dtype=torch.float64)
    for b in range(gt.shape[0]):
        for c in range(3):
            errors = (mask[b, 0] * (gt[b, c] - grid.view(-1, 1, 1) * pred[b, c]) ** 2).sum(
                dim=(1, 2)
            )
            assert abs(float(grid[errors.argmin()]) - float(scale[b, c])) < 2e-4
    # and the PSNR is that of the scaled render over the mask, by hand
    scaled = (scale * pred).clamp(0, 1)
    mse = (mask * (gt - scaled) ** 2).sum(dim=(1, 2, 3)) / (3 * mask.sum(dim=(1, 2, 3)))
    torch.testing.assert_close(scale_invariant_psnr(pred, gt, mask), 10 * torch.log10(1 / mse))


def test_pixels_outside_the_mask_do_not_count():
    gt, mask, gain = _images(3)
    pred = gt * gain
    changed = pred.clone()
    # where the mask is 0
    changed[..., :4, :4] = torch.rand(changed[..., :4, :4].shape, dtype=torch.float64)
    torch.testing.assert_close(
        scale_invariant_psnr(changed, gt, mask), scale_invariant_psnr(pred, gt, mask)
    )
    changed[..., 8, 8] += 0.2  # inside: it counts
    assert torch.all(scale_invariant_psnr(changed, gt, mask) < 60.0)


def test_the_protocol_scores_unmasked_psnr_and_scale_invariant_psnr_over_the_truths_alpha():
    rng = np.random.default_rng(4)
    # even 8-bit levels: × 0.5 stays exact
    gt = (rng.integers(0, 64, (32, 34, 3)) * 2 / 255).astype(np.float32)
    alpha = np.ones((32, 34), np.float32)
    alpha[:3] = 0.0
    pred = gt * 0.5
    pred[:3] = rng.uniform(0, 1, (3, 34, 3))  # outside the object
    scores = get_protocol(NOVEL).evaluate(pred, gt, alpha)
    assert list(scores) == [
        "psnr",
        "psnr_object",
        "psnr_si",
        "ssim",
        "lpips",
        "lpips_alex",
        "lpips_vgg",
    ]
    assert scores["psnr_si"] == 100.0 and scores["psnr"] < 25.0
    # the object, without the scale: the pixels' own error
    inside = (gt[3:].astype(np.float64) - pred[3:]) ** 2
    assert scores["psnr_object"] == pytest.approx(10 * np.log10(1 / inside.mean()), abs=1e-9)


def test_psnr_si_refuses_a_protocol_that_gives_no_alpha():
    protocol = Protocol(
        id="no-alpha", version=1, description="", reproduces="", metric_names=("psnr", "psnr_si")
    )
    image = np.full((8, 8, 3), 0.5, np.float32)
    with pytest.raises(ValueError, match="psnr_si, which needs the ground truth's alpha"):
        protocol.evaluate(image, image)


def test_the_novel_light_protocol_is_named_versioned_and_defined():
    definition = get_protocol(NOVEL).definition()
    assert (
        definition["id"] == NOVEL
        and definition["version"] == 1
        and definition["object_mask"] is True
    )
    assert definition["masked"] is False and "psnr_si" in definition["metrics"]
    assert any("s_c = Σ m·gt·pred / Σ m·pred²" in step for step in definition["steps"])


# --- results.json ---------------------------------------------------------------------------------


def _block(psnr: float = 20.0) -> dict:
    scores = {
        "psnr": psnr,
        "psnr_object": psnr - 1,
        "psnr_si": psnr + 1,
        "ssim": 0.5,
        "lpips": None,
        "lpips_alex": None,
        "lpips_vgg": None,
    }
    condition = {"mean": scores, "per_image": {"000": scores}, "lights": 2}
    return {
        "protocol": {"id": NOVEL, "version": 1},
        "split": "test",
        "options": {"samples": None, "views": None},
        "conditions": {"two_lights": condition},
        "mean": scores,
        "seconds": 1.5,
    }


def _results() -> dict:
    scores = {"psnr": 25.0, "ssim": 0.8, "lpips": 0.1}
    return {
        "schema_version": 2,
        "kind": "run",
        "status": "done",
        "job": {
            "id": "abc",
            "method": "ssdgs",
            "variant": "default",
            "suite": "mini",
            "scene": "s",
            "seed": 0,
            "config": {},
        },
        "protocol": {"id": "olatbench-v1", "version": 1},
        "metrics": {"test": {"mean": scores, "per_image": {"000": scores}}},
    }


def test_results_round_trip_the_novel_lights_block(tmp_path):
    results = {**_results(), "novel_lights": _block()}
    write_results(tmp_path / "results.json", results)
    assert read_results(tmp_path / "results.json") == results
    bad = copy.deepcopy(results)
    bad["novel_lights"]["conditions"]["two_lights"]["mean"]["psnr"] = "high"
    with pytest.raises(
        ResultsError, match=r"novel_lights\.conditions\.two_lights\.mean\.psnr: expected a number"
    ):
        validate_results(bad, "r.json")
    del bad["novel_lights"]["conditions"]["two_lights"]["lights"]
    with pytest.raises(
        ResultsError, match=r"missing keys novel_lights\.conditions\.two_lights\.lights"
    ):
        validate_results(bad, "r.json")


# --- run --evaluate novel-lights, end to end ------------------------------------------------------


def _novel_truth(scene: Path) -> None:
    """Two conditions in the layout of `olatbench.datasets.novel_lights`: two point lights and the
    studio map (4 samples); as ground truth each test frame's own image (linear, straight alpha)."""
    frames = load_scene(scene).split("test")
    lights = [frame.light for frame in load_scene(scene).split("train")[:2]]
    lightings = {
        "two_lights": {
            "lights": [
                {
                    "type": "point",
                    "position": light.position.tolist(),
                    "intensity": light.intensity.tolist(),
                }
                for light in lights
            ]
        },
        "studio": {"lights": [{"type": "envmap", "map": "studio", "samples": 4}]},
    }
    for name, lighting in lightings.items():
        folder = scene / "novel_lights" / name
        folder.mkdir(parents=True)
        (folder / "lighting.json").write_text(json.dumps(lighting))
        (folder / "lit.json").write_text(
            json.dumps({"frames": {frame.frame_id: {} for frame in frames}})
        )
        for frame in frames:
            loaded = frame.load(colourspace="linear", background=None)
            write_image(
                folder / f"{frame.frame_id}.exr",
                np.concatenate([loaded.rgb, loaded.alpha[..., None]], 2),
                bit_depth="float",
            )


def _run(data: Path, out: Path, *extra: str):
    return CliRunner().invoke(
        main,
        [
            "run",
            "-m",
            "ssdgs",
            "--data",
            str(data),
            "--iterations",
            "6",
            "--set",
            "num_init_gaussians=300",
            "--set",
            "shadow_resolution=32",
            "-o",
            str(out),
            "-q",
            "--evaluate",
            "novel-lights",
            *extra,
        ],
    )


@pytest.fixture(scope="module")
def novel_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("novel")
    scene = support.write_tiny_data(root / "data", scenes=("Alpha",)) / "Alpha"
    _novel_truth(scene)
    result = _run(scene, root / "runs")
    assert result.exit_code == 0, result.output
    (folder,) = [path.parent for path in (root / "runs").rglob("results.json")]
    return scene, root / "runs", folder


def test_run_evaluate_novel_lights_writes_scores_and_renders(novel_run):
    scene, _, folder = novel_run
    results = read_results(folder / "results.json")
    block = results["novel_lights"]
    assert block["protocol"] == {"id": NOVEL, "version": 1} and results["protocol"]["id"] != NOVEL
    # CONDITIONS' order first, then others
    assert list(block["conditions"]) == ["two_lights", "studio"]
    assert (
        block["conditions"]["two_lights"]["lights"] == 2
        and block["conditions"]["studio"]["lights"] == 4
    )
    for name, condition in block["conditions"].items():
        assert set(condition["per_image"]) == {"000", "001"}
        assert all(np.isfinite(scores["psnr"]) for scores in condition["per_image"].values())
        assert all(
            (folder / "renders" / "novel_lights" / name / f"{fid}.png").is_file()
            for fid in ("000", "001")
        )
    assert block["mean"]["psnr"] == pytest.approx(
        np.mean([c["mean"]["psnr"] for c in block["conditions"].values()])
    )
    # the in-memory method of the run and the one restored from the checkpoint render the same image
    relighter, _ = restore_relighter(folder)
    from olatbench.bench.novel_lights import with_map_samples
    from olatbench.bench.relight import shown
    from olatbench.datasets.novel_lights import load_condition

    lights = load_condition(scene, "two_lights").lighting.sample(relighter.reference.up)
    frame = load_scene(scene).split("test")[1]
    saved = read_image(folder / "renders" / "novel_lights" / "two_lights" / "001.png")
    assert np.abs(shown(relighter.linear(frame.camera, lights)) - saved).max() <= 0.5 / 255 + 1e-6
    assert (
        with_map_samples(load_condition(scene, "studio").lighting, 7).sample().directions.__len__()
        == 7
    )


def test_a_finished_job_is_scored_from_its_checkpoint_against_its_own_relight(novel_run, tmp_path):
    """The ground truth replaced by the restored model's own relight (alpha 1): rescoring the
    finished job (other options) gives 100 dB, which holds only if cameras, lights, colour space and
    background all agree."""
    scene, runs, folder = novel_run
    relighter, _ = restore_relighter(folder)
    from olatbench.datasets.novel_lights import load_condition

    condition = load_condition(scene, "two_lights")
    lights = condition.lighting.sample(relighter.reference.up)
    for frame in load_scene(scene).split("test"):
        linear = relighter.linear(frame.camera, lights)
        write_image(
            condition.frames[frame.frame_id],
            np.concatenate([linear, np.ones_like(linear[..., :1])], 2),
            bit_depth="float",
        )
    before = (
        (folder / "checkpoints").stat().st_mtime_ns,
        sorted(p.name for p in (folder / "checkpoints").iterdir()),
    )
    result = _run(scene, runs, "--novel-views", "1")
    assert result.exit_code == 0, result.output
    assert "scoring 1 finished job(s) under novel illumination" in result.output
    block = read_results(folder / "results.json")["novel_lights"]
    assert block["options"] == {"samples": None, "views": 1}
    two = block["conditions"]["two_lights"]
    assert (
        list(two["per_image"]) == ["000"]
        and two["mean"]["psnr"] == 100.0
        and two["mean"]["psnr_si"] == 100.0
    )
    assert before == (
        (folder / "checkpoints").stat().st_mtime_ns,
        sorted(p.name for p in (folder / "checkpoints").iterdir()),
    )  # no retraining
    again = _run(scene, runs, "--novel-views", "1")  # scored with these options: nothing to do
    assert again.exit_code == 0 and "under novel illumination" not in again.output


def test_run_evaluate_novel_lights_refuses_a_scene_without_ground_truth(tmp_path):
    scene = support.write_tiny_data(tmp_path / "data", scenes=("Alpha",)) / "Alpha"
    result = _run(scene, tmp_path / "runs")
    assert (
        result.exit_code == 2
        and "novel_lights" in result.output
        and "--evaluate novel-lights" in result.output
    )
    assert not (tmp_path / "runs").exists()
    result = CliRunner().invoke(
        main, ["run", "-m", "ssdgs", "--data", str(scene), "--novel-views", "2"]
    )
    assert result.exit_code == 2 and "go with --evaluate novel-lights" in result.output


def test_report_shows_the_novel_light_table_beside_the_olat_test_scores(novel_run):
    _, runs, _ = novel_run
    result = CliRunner().invoke(main, ["report", str(runs), "--format", "markdown"])
    assert result.exit_code == 0, result.output
    table = result.output[result.output.index("Under novel illumination") :]
    assert (
        "under two_lights" in table and "under studio" in table and "Novel lights (mean)" in table
    )
    assert (
        "PSNR (scale-inv.)" in table
        and "PSNR (object)" in table
        and "olatbench-v1-novel-lights v1" in table
    )
    head = result.output[: result.output.index("Under novel illumination")]
    assert "WARNING: mixed metric protocols" not in head and "under two_lights" not in head
    records = json.loads(
        CliRunner()
        .invoke(
            main,
            [
                "report",
                str(runs),
                "--json",
                "--splits",
                "test,novel:two_lights",
                "--metrics",
                "psnr,psnr_si",
            ],
        )
        .output
    )
    assert {(r["split"], r["metric"]) for r in records if r["split"] != "-"} == {
        ("test", "psnr"),
        ("novel:two_lights", "psnr"),
        ("novel:two_lights", "psnr_si"),
    }
    novel = [r for r in records if r["split"] == "novel:two_lights"]
    assert all(r["protocol"] == {"id": NOVEL, "version": 1} and r["value"] == 100.0 for r in novel)
