"""A user's own scenes through the runner: ``run --data`` folders (format detected, settings from
the format's suite) and ``[suites.NAME]`` of olatbench.toml, usable as ``-s NAME`` by run, status,
report and view."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import test_runner_support as support  # noqa: F401  (registers the 'trivial' method and the 'test-fast' protocol)
from click.testing import CliRunner
from datasets_trees import write_nrhints_tree

from olatbench.bench.results import read_results
from olatbench.cli import main
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.suites import SUITES, data_suites, get_suite, user_suites


def _invoke(*args: str, **kwargs):
    return CliRunner().invoke(main, [str(arg) for arg in args], **kwargs)


def _plan(*args: str) -> list[dict]:
    result = _invoke("run", *args, "--dry-run", "--json")
    assert result.exit_code == 0, result.output
    return json.loads(result.output)


def test_data_folders_take_their_formats_suite_settings_and_their_own_run_folders(tmp_path):
    write_nrhints_tree(tmp_path / "captures" / "Cup", n_train=3, n_test=1, size=(16, 12))
    (suite,) = data_suites([tmp_path / "captures" / "Cup"])
    nrhints = SUITES["nrhints"]
    assert (suite.name, suite.format, suite.scenes) == ("data-nrhints", "nrhints", ("Cup",))
    assert (suite.protocol, suite.resolution, suite.iterations) == (
        nrhints.protocol,
        nrhints.resolution,
        nrhints.iterations,
    )
    assert suite.scene_path(None, "Cup") == (tmp_path / "captures" / "Cup").resolve()

    jobs = _plan(
        "-m",
        "trivial",
        "--data",
        tmp_path / "captures" / "Cup",
        "-o",
        tmp_path / "runs",
        "--iterations",
        "5",
        "--protocol",
        "test-fast",
    )
    assert [(job["suite"], job["scene"], job["iterations"]) for job in jobs] == [
        ("data-nrhints", "Cup", 5)
    ]
    # never a suite's folder
    assert jobs[0]["folder"] == "data-nrhints/trivial/default~iterations=5/Cup/seed0"
    assert get_suite("data-nrhints").format == "nrhints"  # report/status/view know the name
    with pytest.raises(DatasetError, match="unknown suite 'data-nope'"):
        get_suite("data-nope")


def test_data_folder_errors_are_usage_errors(tmp_path):
    write_nrhints_tree(tmp_path / "a" / "Cup", n_train=3, n_test=1, size=(16, 12))
    write_nrhints_tree(tmp_path / "b" / "Cup", n_train=3, n_test=1, size=(16, 12))
    (tmp_path / "empty").mkdir()
    cases = [
        (
            ["--data", tmp_path / "a" / "Cup", "--data", tmp_path / "b" / "Cup"],
            "two scene folders are named 'Cup'",
        ),
        (["--data", tmp_path / "empty"], "no known dataset format"),
        (["--data", tmp_path / "a" / "Cup", "-s", "mini"], "not both"),
        ([], "give --suite NAME or --data"),
        (["--data", tmp_path / "a" / "Cup", "--protocol", "nope"], "nope"),
        (["--data", tmp_path / "a" / "Cup", "--data-root", tmp_path], "--data-root is for --suite"),
    ]
    for args, message in cases:
        result = _invoke("run", "-m", "trivial", *args, "-o", tmp_path / "runs", "--dry-run")
        assert result.exit_code == 2 and message in result.output, (args, result.output)


def _write_toml(folder: Path, text: str) -> None:
    (folder / "olatbench.toml").write_text(text, encoding="utf-8")


def test_user_suite_in_olatbench_toml_is_a_suite_everywhere(tmp_path, monkeypatch):
    write_nrhints_tree(tmp_path / "captures" / "Cup", n_train=3, n_test=1, size=(16, 12))
    write_nrhints_tree(tmp_path / "captures" / "Mug", n_train=3, n_test=1, size=(16, 12))
    _write_toml(
        tmp_path,
        '[suites.mine]\nscenes = ["captures/Cup", "captures/Mug"]\nprotocol = "test-fast"\n'
        'resolution = "16x12"\niterations = 3\n',
    )
    monkeypatch.chdir(tmp_path)
    suite = user_suites()["mine"]
    assert (suite.format, suite.scenes, suite.resolution, suite.iterations, suite.protocol) == (
        "nrhints",
        ("Cup", "Mug"),
        (16, 12),
        3,
        "test-fast",
    )
    assert "mine" in [*SUITES, *user_suites()] and get_suite("mine") == suite

    jobs = _plan("-m", "trivial", "-s", "mine", "-o", "runs")
    assert [(job["suite"], job["scene"], job["iterations"]) for job in jobs] == [
        ("mine", "Cup", 3),
        ("mine", "Mug", 3),
    ]
    result = _invoke("run", "-m", "trivial", "-s", "mine", "--scenes", "Mug", "-o", "runs", "-q")
    assert result.exit_code == 0, result.output
    results = read_results(Path("runs/mine/trivial/default/Mug/seed0/results.json"))
    assert results["job"]["resolution"] == [16, 12] and results["protocol"]["id"] == "test-fast"

    status = _invoke("status", "runs", "-s", "mine", "--json")
    assert status.exit_code == 0 and [row["job"] for row in json.loads(status.output)] == [
        "mine/trivial/default/Mug/seed0"
    ]
    report = _invoke("report", "runs", "-s", "mine", "--metrics", "psnr")
    assert report.exit_code == 0 and "Per-scene results on the mine suite" in report.output, (
        report.output
    )
    # Cup not run yet: marked
    assert "| trivial |" in report.output and "—<sup>b</sup>" in report.output
    for verb in (["status", "runs"], ["report", "runs"], ["view", "runs"]):
        result = _invoke(*verb, "-s", "other")
        assert result.exit_code == 2 and "unknown suite 'other'" in result.output, (
            verb,
            result.output,
        )


def test_a_user_suite_trains_in_the_fitted_frame_unless_it_keeps_the_datas_own(
    tmp_path, monkeypatch
):
    write_nrhints_tree(tmp_path / "Cup", n_train=3, n_test=1, size=(16, 12))
    _write_toml(
        tmp_path,
        '[suites.mine]\nscenes = ["Cup"]\n[suites.as_is]\nscenes = ["Cup"]\nframe = "dataset"\n',
    )
    monkeypatch.chdir(tmp_path)
    assert (user_suites()["mine"].frame, user_suites()["as_is"].frame) == ("fitted", "dataset")
    (fitted,) = _plan("-m", "trivial", "-s", "mine", "-o", "runs")
    (as_is,) = _plan("-m", "trivial", "-s", "as_is", "-o", "runs")
    assert (fitted["frame"], as_is["frame"]) == ("fitted", "dataset")
    assert fitted["id"] != as_is["id"]  # the frame is part of the job's identity
    (official,) = _plan("-m", "ssdgs-official", "-s", "mine", "-o", "runs")
    assert official["frame"] == "dataset"  # the authors' code reads the files as they are
    shown = _invoke("run", "-m", "ssdgs", "-s", "as_is", "-o", "runs", "--dry-run")
    assert shown.exit_code == 0 and "frame: the data's own world frame" in shown.output, (
        shown.output
    )


def test_malformed_user_suites_name_the_file_table_and_key(tmp_path, monkeypatch):
    write_nrhints_tree(tmp_path / "Cup", n_train=3, n_test=1, size=(16, 12))
    monkeypatch.chdir(tmp_path)
    for text, message in [
        ('[suites.mine]\nscenes = ["Cup"]\ncolour = "red"\n', "unknown key(s) colour"),
        ('[suites.mine]\nscenes = "Cup"\n', "scenes must be a non-empty list"),
        ('[suites.mine]\nscenes = ["Cup"]\nformat = "gs3"\n', "in nrhints format, not gs3"),
        ('[suites.mine]\nscenes = ["Cup"]\nresolution = "big"\n', "resolution must be N, WxH"),
        ('[suites.gs3]\nscenes = ["Cup"]\n', "the name is taken"),
        ('[suites.data-x]\nscenes = ["Cup"]\n', "reserved for run --data"),
        ('[suites.mine]\nscenes = ["Nope"]\n', "not a folder"),
        (
            '[suites.mine]\nscenes = ["Cup"]\nframe = "world"\n',
            "frame must be one of fitted, dataset",
        ),
    ]:
        _write_toml(tmp_path, text)
        with pytest.raises(DatasetError, match=r"olatbench\.toml") as caught:
            user_suites()
        assert message in str(caught.value) and "[suites." in str(caught.value), text
        result = _invoke("run", "-m", "trivial", "-s", "mine", "--dry-run")
        assert result.exit_code == 2 and message in result.output, (text, result.output)


def _synth_gs3(out: Path) -> None:
    pytest.importorskip("mitsuba")
    result = _invoke(
        "datasets",
        "synth",
        "--recipe",
        "diffuse_shadow",
        "--format",
        "gs3",
        "-o",
        out,
        "--resolution",
        "24",
        "--spp",
        "4",
        "--train",
        "4",
        "--test",
        "2",
        "--no-geometry",
        "-q",
    )
    assert result.exit_code == 0, result.output


def test_own_gs3_scene_runs_at_two_lengths_into_separate_folders_and_rows(tmp_path):
    _synth_gs3(tmp_path / "scene")
    runs = tmp_path / "runs"
    for steps in ("5", "8"):
        result = _invoke(
            "run",
            "-m",
            "3dgs",
            "--data",
            tmp_path / "scene",
            "--iterations",
            steps,
            "--resolution",
            "24x24",
            "-o",
            runs,
            "-q",
        )
        assert result.exit_code == 0, result.output
    folders = sorted(p.parent.relative_to(runs).as_posix() for p in runs.rglob("results.json"))
    assert folders == [
        "data-gs3/3dgs/default~iterations=5/scene/seed0",
        "data-gs3/3dgs/default~iterations=8/scene/seed0",
    ]
    report = _invoke("report", runs, "--metrics", "psnr", "--splits", "test")
    assert report.exit_code == 0, report.output
    # the label rule (reports/experiments.py): the overrides; 24x24 is the scene's own size, where a
    # scene of one's own trains anyway (#46), so it is the same experiment as not asking and names
    # no resolution
    assert "| 3dgs (iterations=5) |" in report.output
    assert "| 3dgs (iterations=8) |" in report.output
    assert "±" not in report.output and "mean over 1 seed" in report.output
    rows = json.loads(_invoke("report", runs, "--json").output)
    assert {row["config"]["iterations"] for row in rows} == {5, 8}
    assert all(isinstance(row["value"], float) for row in rows if row["metric"] == "psnr")


@pytest.mark.slow
def test_done_when_own_gs3_scene_at_the_formats_settings(tmp_path, monkeypatch):
    """The issue's command as given: `olatbench run -m 3dgs --data DIR --iterations 5` (the scene's
    own 24², GS³'s protocol), then `olatbench report`."""
    _synth_gs3(tmp_path / "DIR")
    monkeypatch.chdir(tmp_path)
    result = _invoke("run", "-m", "3dgs", "--data", "DIR", "--iterations", "5", "-q")
    assert result.exit_code == 0, result.output
    results = read_results(next(Path("runs").rglob("results.json")))
    # native
    assert (
        results["job"]["resolution"] is None and results["protocol"]["id"] == SUITES["gs3"].protocol
    )
    report = _invoke("report")
    assert report.exit_code == 0 and "data-gs3" in report.output and "| 3dgs |" in report.output, (
        report.output
    )
    shutil.rmtree("runs")


def test_own_suites_derive_the_preset_from_the_scene_and_keep_the_formats_without_a_recipe(
    tmp_path, monkeypatch
):
    write_nrhints_tree(tmp_path / "Cup", n_train=3, n_test=1, size=(16, 12))
    from olatbench.methods import registry

    spec = registry.get_spec("3dgs")
    mini, nrhints = spec.presets["mini"], spec.presets["nrhints"]
    (job,) = _plan("-m", "3dgs", "--data", tmp_path / "Cup", "-o", tmp_path / "runs")
    # a 16x12 scene of 3 images is smaller than the mini scenes the recipe was tuned on: the recipe
    # as it is
    assert {key: job["config"][key] for key in mini} == dict(mini)
    assert job["config"]["max_gaussians"] != nrhints["max_gaussians"]  # not the paper's 550,000
    assert set(job["derived"]) >= {"iterations", "max_gaussians", "num_init_gaussians"}
    assert job["resolution"] == "native"
    _write_toml(tmp_path, '[suites.mine]\nscenes = ["Cup"]\niterations = 7\n')
    monkeypatch.chdir(tmp_path)
    (job,) = _plan("-m", "3dgs", "-s", "mine", "-o", "runs")
    # the suite's own count
    assert job["iterations"] == 7 and job["derived"]["iterations"]["why"] == "as asked"
    assert job["config"]["position_lr_max_steps"] == mini["position_lr_max_steps"]
    # a method that declares no scene recipe keeps its format's preset, as before
    monkeypatch.setitem(registry._registered, "3dgs", dataclasses.replace(spec, scene_recipe=None))
    (job,) = _plan("-m", "3dgs", "--data", tmp_path / "Cup", "-o", tmp_path / "runs")
    assert {key: job["config"][key] for key in nrhints} == dict(nrhints) and job["derived"] == {}


def test_a_white_scene_is_trained_and_scored_on_white_whatever_the_protocol(tmp_path):
    """An NRHints synthetic scene of one's own (``camera_angle_x``, no ``camera_intrinsics``, no
    synth.json: white, as NRHints trains these) is trained on white and scored against ground truth
    on white by every path: the runner's results.json (protocol ssdgs, whose ground truth is the
    official loader's image), `olatbench evaluate` and every protocol's ground truth. Before #58 the
    official ground truth composited on black: 5.4 dB against 11.4 dB on a 48² glossy-plastic
    scene."""
    from olatbench.bench.views import load_views
    from olatbench.datasets import load_scene
    from olatbench.datasets.images import read_image
    from olatbench.metrics.protocols import get_protocol, protocol_names

    tree = write_nrhints_tree(
        tmp_path / "Own", n_train=4, n_test=2, size=(24, 16), intrinsics=False
    )
    scene = load_scene(tmp_path / "Own")
    assert scene.background.tolist() == [1.0, 1.0, 1.0]
    result = _invoke(
        "run",
        "-m",
        "trivial",
        "--data",
        tmp_path / "Own",
        "-o",
        tmp_path / "runs",
        "--iterations",
        "30",
        "--quiet",
        "--device",
        "cpu",
    )
    assert result.exit_code == 0, result.output
    (results_file,) = (tmp_path / "runs").rglob("results.json")
    results = read_results(results_file)
    assert results["protocol"]["id"] == "ssdgs"
    # independent of olatbench's compositing: the loader's arithmetic on the stored pixels, on white
    # and on black
    for index, frame in enumerate(scene.split("test")):
        stored = tree.frames["test"][index]["stored"].astype(np.float64)
        rgb, alpha = stored[..., :3], stored[..., 3:]
        render = read_image(results_file.parent / "renders" / "test" / f"{frame.frame_id}.png")[
            ..., :3
        ]
        white, black = (
            _truncated_psnr(render, rgb * alpha + background * (1 - alpha))
            for background in (1.0, 0.0)
        )
        scored = results["metrics"]["test"]["per_image"][frame.frame_id]["psnr"]
        assert abs(scored - white) < 1e-3, (scored, white, black)
        assert abs(white - black) > 1.0  # the scene tells the two backgrounds apart
    # the training views and every protocol's ground truth composite on the same white
    job_views = load_views(scene.split("train"), _data_job(tmp_path / "Own"))
    assert job_views.background.tolist() == [1.0, 1.0, 1.0]
    for frame in scene.split("train"):
        expected = frame.load(colourspace="srgb", background="official").rgb
        for name in protocol_names():
            truth, _ = get_protocol(name).load_ground_truth(frame, scene.format)
            assert np.abs(truth - expected).max() <= 1 / 255 + 1e-6, name
    # `olatbench evaluate` of the runner's renders gives the runner's numbers
    evaluated = _invoke(
        "evaluate",
        results_file.parent / "renders" / "test",
        "--gt",
        tmp_path / "Own",
        "--protocol",
        "ssdgs",
        "-o",
        tmp_path / "evaluated.json",
    )
    assert evaluated.exit_code == 0, evaluated.output
    again = json.loads((tmp_path / "evaluated.json").read_text())["metrics"]["test"]["per_image"]
    for frame_id, scores in results["metrics"]["test"]["per_image"].items():
        assert abs(again[frame_id]["psnr"] - scores["psnr"]) < 1e-6


def _truncated_psnr(render: np.ndarray, composite: np.ndarray) -> float:
    """PSNR (dB) of ``render`` against ``composite`` truncated to 8 bits, as the GS³ / SSD-GS loader
    stores it."""
    truth = np.floor(composite * 255.0 + 1e-9) / 255.0
    return float(10 * np.log10(1 / np.mean((render.astype(np.float64) - truth) ** 2)))


def _data_job(folder: Path):
    """The job `run -m trivial --data FOLDER` plans (test protocol, 5 steps)."""
    from olatbench.bench.plan import make_plan

    (suite,) = data_suites([folder])
    return make_plan("trivial", suite, folder.parent / "plan", iterations=5, progress=False)[0]
