"""A user's own scenes through the runner: ``run --data`` folders (format detected, settings from the format's suite)
and ``[suites.NAME]`` of olatbench.toml, usable as ``-s NAME`` by run, status, report and view."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

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
    assert (suite.protocol, suite.resolution, suite.iterations) == (nrhints.protocol, nrhints.resolution,
                                                                  nrhints.iterations)
    assert suite.scene_path(None, "Cup") == (tmp_path / "captures" / "Cup").resolve()

    jobs = _plan("-m", "trivial", "--data", tmp_path / "captures" / "Cup", "-o", tmp_path / "runs",
                 "--iterations", "5", "--protocol", "test-fast")
    assert [(job["suite"], job["scene"], job["iterations"]) for job in jobs] == [("data-nrhints", "Cup", 5)]
    assert jobs[0]["folder"] == "data-nrhints/trivial/default~iterations=5/Cup/seed0"  # never a suite's folder
    assert get_suite("data-nrhints").format == "nrhints"  # report/status/view know the name
    with pytest.raises(DatasetError, match="unknown suite 'data-nope'"):
        get_suite("data-nope")


def test_data_folder_errors_are_usage_errors(tmp_path):
    write_nrhints_tree(tmp_path / "a" / "Cup", n_train=3, n_test=1, size=(16, 12))
    write_nrhints_tree(tmp_path / "b" / "Cup", n_train=3, n_test=1, size=(16, 12))
    (tmp_path / "empty").mkdir()
    cases = [
        (["--data", tmp_path / "a" / "Cup", "--data", tmp_path / "b" / "Cup"], "two scene folders are named 'Cup'"),
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
    _write_toml(tmp_path, '[suites.mine]\nscenes = ["captures/Cup", "captures/Mug"]\nprotocol = "test-fast"\n'
                          'resolution = "16x12"\niterations = 3\n')
    monkeypatch.chdir(tmp_path)
    suite = user_suites()["mine"]
    assert (suite.format, suite.scenes, suite.resolution, suite.iterations, suite.protocol) == (
        "nrhints", ("Cup", "Mug"), (16, 12), 3, "test-fast")
    assert "mine" in [*SUITES, *user_suites()] and get_suite("mine") == suite

    jobs = _plan("-m", "trivial", "-s", "mine", "-o", "runs")
    assert [(job["suite"], job["scene"], job["iterations"]) for job in jobs] == [("mine", "Cup", 3), ("mine", "Mug", 3)]
    result = _invoke("run", "-m", "trivial", "-s", "mine", "--scenes", "Mug", "-o", "runs", "-q")
    assert result.exit_code == 0, result.output
    results = read_results(Path("runs/mine/trivial/default/Mug/seed0/results.json"))
    assert results["job"]["resolution"] == [16, 12] and results["protocol"]["id"] == "test-fast"

    status = _invoke("status", "runs", "-s", "mine", "--json")
    assert status.exit_code == 0 and [row["job"] for row in json.loads(status.output)] == [
        "mine/trivial/default/Mug/seed0"]
    report = _invoke("report", "runs", "-s", "mine", "--metrics", "psnr")
    assert report.exit_code == 0 and "Per-scene results on the mine suite" in report.output, report.output
    assert "| trivial |" in report.output and "—<sup>b</sup>" in report.output  # Cup not run yet: marked
    for verb in (["status", "runs"], ["report", "runs"], ["view", "runs"]):
        result = _invoke(*verb, "-s", "other")
        assert result.exit_code == 2 and "unknown suite 'other'" in result.output, (verb, result.output)


def test_a_user_suite_trains_in_the_fitted_frame_unless_it_keeps_the_datas_own(tmp_path, monkeypatch):
    write_nrhints_tree(tmp_path / "Cup", n_train=3, n_test=1, size=(16, 12))
    _write_toml(tmp_path, '[suites.mine]\nscenes = ["Cup"]\n[suites.as_is]\nscenes = ["Cup"]\nframe = "dataset"\n')
    monkeypatch.chdir(tmp_path)
    assert (user_suites()["mine"].frame, user_suites()["as_is"].frame) == ("fitted", "dataset")
    (fitted,) = _plan("-m", "trivial", "-s", "mine", "-o", "runs")
    (as_is,) = _plan("-m", "trivial", "-s", "as_is", "-o", "runs")
    assert (fitted["frame"], as_is["frame"]) == ("fitted", "dataset")
    assert fitted["id"] != as_is["id"]  # the frame is part of the job's identity
    (official,) = _plan("-m", "ssdgs-official", "-s", "mine", "-o", "runs")
    assert official["frame"] == "dataset"  # the authors' code reads the files as they are
    shown = _invoke("run", "-m", "ssdgs", "-s", "as_is", "-o", "runs", "--dry-run")
    assert shown.exit_code == 0 and "frame: the data's own world frame" in shown.output, shown.output


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
        ('[suites.mine]\nscenes = ["Cup"]\nframe = "world"\n', "frame must be one of fitted, dataset"),
    ]:
        _write_toml(tmp_path, text)
        with pytest.raises(DatasetError, match=r"olatbench\.toml") as caught:
            user_suites()
        assert message in str(caught.value) and "[suites." in str(caught.value), text
        result = _invoke("run", "-m", "trivial", "-s", "mine", "--dry-run")
        assert result.exit_code == 2 and message in result.output, (text, result.output)


def _synth_gs3(out: Path) -> None:
    pytest.importorskip("mitsuba")
    result = _invoke("datasets", "synth", "--recipe", "diffuse_shadow", "--format", "gs3", "-o", out,
                     "--resolution", "24", "--spp", "4", "--train", "4", "--test", "2", "--no-geometry", "-q")
    assert result.exit_code == 0, result.output


def test_own_gs3_scene_runs_at_two_lengths_into_separate_folders_and_rows(tmp_path):
    _synth_gs3(tmp_path / "scene")
    runs = tmp_path / "runs"
    for steps in ("5", "8"):
        result = _invoke("run", "-m", "3dgs", "--data", tmp_path / "scene", "--iterations", steps,
                         "--resolution", "24x24", "-o", runs, "-q")
        assert result.exit_code == 0, result.output
    folders = sorted(p.parent.relative_to(runs).as_posix() for p in runs.rglob("results.json"))
    assert folders == ["data-gs3/3dgs/default~iterations=5/scene/seed0",
                       "data-gs3/3dgs/default~iterations=8/scene/seed0"]
    report = _invoke("report", runs, "--metrics", "psnr", "--splits", "test")
    assert report.exit_code == 0, report.output
    # the label rule (reports/experiments.py): the overrides; 24x24 is the scene's own size, where a scene of one's
    # own trains anyway (#46), so it is the same experiment as not asking and names no resolution
    assert "| 3dgs (iterations=5) |" in report.output
    assert "| 3dgs (iterations=8) |" in report.output
    assert "±" not in report.output and "mean over 1 seed" in report.output
    rows = json.loads(_invoke("report", runs, "--json").output)
    assert {row["config"]["iterations"] for row in rows} == {5, 8}
    assert all(isinstance(row["value"], float) for row in rows if row["metric"] == "psnr")


@pytest.mark.slow
def test_done_when_own_gs3_scene_at_the_formats_settings(tmp_path, monkeypatch):
    """The issue's command as given: `olatbench run -m 3dgs --data DIR --iterations 5` (the scene's own 24², GS³'s
    protocol), then `olatbench report`."""
    _synth_gs3(tmp_path / "DIR")
    monkeypatch.chdir(tmp_path)
    result = _invoke("run", "-m", "3dgs", "--data", "DIR", "--iterations", "5", "-q")
    assert result.exit_code == 0, result.output
    results = read_results(next(Path("runs").rglob("results.json")))
    assert results["job"]["resolution"] is None and results["protocol"]["id"] == SUITES["gs3"].protocol  # native
    report = _invoke("report")
    assert report.exit_code == 0 and "data-gs3" in report.output and "| 3dgs |" in report.output, report.output
    shutil.rmtree("runs")


def test_own_suites_derive_the_preset_from_the_scene_and_keep_the_formats_without_a_recipe(tmp_path, monkeypatch):
    write_nrhints_tree(tmp_path / "Cup", n_train=3, n_test=1, size=(16, 12))
    from olatbench.methods import registry

    spec = registry.get_spec("3dgs")
    mini, nrhints = spec.presets["mini"], spec.presets["nrhints"]
    (job,) = _plan("-m", "3dgs", "--data", tmp_path / "Cup", "-o", tmp_path / "runs")
    # a 16x12 scene of 3 images is smaller than the mini scenes the recipe was tuned on: the recipe as it is
    assert {key: job["config"][key] for key in mini} == dict(mini)
    assert job["config"]["max_gaussians"] != nrhints["max_gaussians"]  # not the paper's 550,000
    assert set(job["derived"]) >= {"iterations", "max_gaussians", "num_init_gaussians"}
    assert job["resolution"] == "native"
    _write_toml(tmp_path, '[suites.mine]\nscenes = ["Cup"]\niterations = 7\n')
    monkeypatch.chdir(tmp_path)
    (job,) = _plan("-m", "3dgs", "-s", "mine", "-o", "runs")
    assert job["iterations"] == 7 and job["derived"]["iterations"]["why"] == "as asked"  # the suite's own count
    assert job["config"]["position_lr_max_steps"] == mini["position_lr_max_steps"]
    # a method that declares no scene recipe keeps its format's preset, as before
    monkeypatch.setitem(registry._registered, "3dgs", dataclasses.replace(spec, scene_recipe=None))
    (job,) = _plan("-m", "3dgs", "--data", tmp_path / "Cup", "-o", tmp_path / "runs")
    assert {key: job["config"][key] for key in nrhints} == dict(nrhints) and job["derived"] == {}
