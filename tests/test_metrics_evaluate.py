"""``olatbench evaluate``: matching predictions to frames, refusing bad folders, the result JSON."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from datasets_trees import write_nrhints_tree

from olatbench.cli.metrics import evaluate, explain, list_protocols, where
from olatbench.datasets import load_scene
from olatbench.datasets.images import write_image
from olatbench.datasets.official import official_ground_truth
from olatbench.metrics.evaluate import (
    EvaluationError,
    evaluate_folder,
    match_predictions,
    sha256_file,
)
from olatbench.metrics.protocols import get_protocol

SIZE = (40, 36)


@pytest.fixture
def scene(tmp_path) -> Path:
    write_nrhints_tree(tmp_path / "Cat", n_train=1, n_test=3, size=SIZE, seed=3)
    return tmp_path / "Cat"


def write_predictions(scene: Path, out: Path, noise: float = 0.0) -> list[str]:
    """Ground truth as the benchmark sees it (composited sRGB), optionally perturbed, as 8-bit
    PNGs."""
    rng = np.random.default_rng(0)
    ids = []
    for frame in load_scene(scene).split("test"):
        rgb = frame.load(colourspace="srgb").rgb
        write_image(
            out / f"{frame.frame_id}.png",
            np.clip(rgb + noise * rng.standard_normal(rgb.shape), 0, 1),
        )
        ids.append(frame.frame_id)
    return ids


def test_match_predictions_reports_missing_extra_and_ambiguous(tmp_path):
    for name in ("a.png", "b.png", "b.exr", "zz.png", "notes.txt"):
        (tmp_path / name).write_bytes(b"x")
    with pytest.raises(EvaluationError) as info:
        match_predictions(tmp_path, ["a", "b", "c"])
    message = str(info.value)
    assert "missing predictions for frames (1): c" in message
    assert "several files for one frame (1): b (b.exr, b.png)" in message
    assert (
        "files matching no ground-truth frame (1): zz.png" in message and "notes.txt" not in message
    )
    assert match_predictions(tmp_path, ["a", "zz"], allow_extra=True) == {
        "a": tmp_path / "a.png",
        "zz": tmp_path / "zz.png",
    }


def test_perfect_predictions_and_result_json(scene, tmp_path):
    ids = write_predictions(scene, tmp_path / "pred")
    result = evaluate_folder(tmp_path / "pred", scene, "test", get_protocol("olatbench-v1"))
    block = result["metrics"]["test"]
    assert sorted(block["per_image"]) == sorted(ids)
    assert block["mean"]["psnr"] == 100.0 and block["mean"]["ssim"] == pytest.approx(1.0, abs=1e-6)
    assert block["mean"]["lpips"] in (0.0, None)
    assert result["protocol"]["id"] == "olatbench-v1" and result["protocol"]["version"] == 1
    first = result["files"]["test"][ids[0]]
    assert first["render_sha256"] == sha256_file(tmp_path / "pred" / f"{ids[0]}.png")
    assert first["ground_truth_sha256"] == sha256_file(Path(first["ground_truth"]))
    assert result["source"]["split"] == "test" and result["source"]["scene"]["format"] == "nrhints"


def test_noisy_predictions_match_direct_protocol_call(scene, tmp_path):
    write_predictions(scene, tmp_path / "pred", noise=0.05)
    protocol = get_protocol("nrhints")
    result = evaluate_folder(tmp_path / "pred", scene, "test", protocol)
    frame = load_scene(scene).split("test")[1]
    from olatbench.datasets.images import read_image

    pred = read_image(tmp_path / "pred" / f"{frame.frame_id}.png")
    direct = protocol.evaluate(pred, frame.load(colourspace="srgb").rgb)
    assert result["metrics"]["test"]["per_image"][frame.frame_id]["psnr"] == pytest.approx(
        direct["psnr"]
    )
    assert 15 < direct["psnr"] < 40


def test_ssdgs_scores_against_the_official_truncated_ground_truth(scene, tmp_path):
    frame = load_scene(scene).split("test")[0]
    official = official_ground_truth(frame, "nrhints")
    rgb, _ = get_protocol("ssdgs").load_ground_truth(frame, "nrhints")
    np.testing.assert_array_equal(rgb, official)
    rgb_v1, _ = get_protocol("olatbench-v1").load_ground_truth(frame, "nrhints")
    assert not np.array_equal(rgb_v1, official)  # rounding vs the loader's truncation


def test_masked_protocol_uses_alpha(scene, tmp_path):
    write_predictions(scene, tmp_path / "pred", noise=0.05)
    result = evaluate_folder(tmp_path / "pred", scene, "test", get_protocol("olatbench-v1-masked"))
    assert result["metrics"]["test"]["mean"]["psnr"] < 100


def test_cli_refuses_missing_extra_corrupt_and_overwrite(scene, tmp_path):
    runner = CliRunner()
    pred = tmp_path / "pred"
    ids = write_predictions(scene, pred)
    out = tmp_path / "res.json"
    args = [str(pred), "--gt", str(scene), "-o", str(out), "--protocol", "nrhints"]
    ok = runner.invoke(evaluate, args)
    assert ok.exit_code == 0, ok.output
    assert "nrhints v1, test, 3 images" in ok.output and out.is_file()
    first = out.read_bytes()
    again = runner.invoke(evaluate, args)
    assert again.exit_code != 0 and "--overwrite" in again.output
    (pred / "999.png").write_bytes((pred / f"{ids[0]}.png").read_bytes())
    extra = runner.invoke(evaluate, [*args, "--overwrite"])
    assert extra.exit_code != 0 and "999.png" in extra.output and "Traceback" not in extra.output
    assert runner.invoke(evaluate, [*args, "--overwrite", "--allow-extra"]).exit_code == 0
    first = out.read_bytes()
    (pred / "999.png").unlink()
    (pred / f"{ids[1]}.png").write_bytes(b"\x89PNG not really")
    corrupt = runner.invoke(evaluate, [*args, "--overwrite"])
    assert (
        corrupt.exit_code != 0
        and f"frame {ids[1]}" in corrupt.output
        and f"{ids[1]}.png" in corrupt.output
    )
    (pred / f"{ids[1]}.png").unlink()
    missing = runner.invoke(evaluate, [*args, "--overwrite"])
    assert (
        missing.exit_code != 0 and f"missing predictions for frames (1): {ids[1]}" in missing.output
    )
    assert out.read_bytes() == first  # failed runs leave the result untouched


def test_cli_require_lpips_without_weights(scene, tmp_path, no_lpips_weights):
    write_predictions(scene, tmp_path / "pred")
    result = CliRunner().invoke(
        evaluate, [str(tmp_path / "pred"), "--gt", str(scene), "--require", "lpips"]
    )
    assert result.exit_code != 0 and "olatbench weights install" in result.output
    soft = CliRunner().invoke(
        evaluate, [str(tmp_path / "pred"), "--gt", str(scene), "--protocol", "nrhints"]
    )
    assert soft.exit_code == 0 and "lpips=None" in soft.output
    assert soft.output.count("warning: LPIPS-alex is reported as None") == 1
    shown = CliRunner().invoke(where, [])
    assert "not found" in shown.output and "olatbench weights install" in shown.output


def test_metrics_list_and_explain():
    runner = CliRunner()
    listing = runner.invoke(list_protocols, [])
    assert "olatbench-v1" in listing.output and "ssdgs" in listing.output
    text = runner.invoke(explain, ["ssdgs"])
    assert text.exit_code == 0 and "ZERO padding" in text.output
    as_json = json.loads(runner.invoke(explain, ["nrhints", "--json"]).output)
    assert as_json == get_protocol("nrhints").definition()
    assert runner.invoke(explain, ["nope"]).exit_code != 0


def test_ssdgs_on_gs3_scores_in_the_official_gamma22_space(tmp_path):
    from datasets_trees import write_gs3_tree

    write_gs3_tree(tmp_path / "Lego", n_train=1, n_test=2, size=SIZE)
    scene = load_scene(tmp_path / "Lego")
    for frame in scene.split("test"):
        write_image(
            tmp_path / "pred" / f"{frame.frame_id}.png", official_ground_truth(frame, "gs3")
        )
    result = evaluate_folder(
        tmp_path / "pred", tmp_path / "Lego", "test", get_protocol("ssdgs"), png_space="gamma22"
    )
    assert result["source"]["colourspace"] == "gamma22"
    assert result["metrics"]["test"]["mean"]["psnr"] == 100.0
    as_srgb = evaluate_folder(tmp_path / "pred", tmp_path / "Lego", "test", get_protocol("ssdgs"))
    # the same files read as sRGB are other values
    assert as_srgb["metrics"]["test"]["mean"]["psnr"] < 60
    # every protocol scores GS³ data in its display space (the runner does too); olatbench-v1's
    # ground truth is the float composite without the official loader's alpha quirk and 8-bit
    # rounding: close, not equal
    v1 = evaluate_folder(
        tmp_path / "pred",
        tmp_path / "Lego",
        "test",
        get_protocol("olatbench-v1"),
        png_space="gamma22",
    )
    assert v1["source"]["colourspace"] == "gamma22"
    assert 30 < v1["metrics"]["test"]["mean"]["psnr"] < 100, v1["metrics"]["test"]["mean"]


def test_cli_writes_the_runners_results_schema(scene, tmp_path):
    """`olatbench evaluate` writes a results.json of the current schema (kind "evaluate") with the
    runner's provenance keys: the same version and library key names, timestamps, hardware and
    per-file sha256."""
    from olatbench.bench.provenance import library_versions
    from olatbench.bench.results import SCHEMA_VERSION, Results, read_results

    ids = write_predictions(scene, tmp_path / "pred")
    out = tmp_path / "scored.json"
    result = CliRunner().invoke(
        evaluate, [str(tmp_path / "pred"), "--gt", str(scene), "-o", str(out)]
    )
    assert result.exit_code == 0, result.output
    data = read_results(out)
    assert (
        data["schema_version"] == SCHEMA_VERSION
        and data["kind"] == "evaluate"
        and data["job"] is None
    )
    # all but official's
    assert set(Results.__annotations__) - {"method_kind", "official"} <= set(data)
    assert set(data["versions"]) == set(library_versions())
    assert data["timing"]["started"] <= data["timing"]["finished"]
    assert data["hardware"]["cpu"]["threads"] >= 1
    assert data["protocol"]["definition"] == get_protocol("olatbench-v1").definition()
    assert data["source"]["predictions"] == str((tmp_path / "pred").resolve())
    entry = data["files"]["test"][ids[0]]
    assert entry["render_sha256"] == sha256_file(tmp_path / "pred" / f"{ids[0]}.png")
    assert entry["ground_truth_sha256"] == sha256_file(Path(entry["ground_truth"]))
