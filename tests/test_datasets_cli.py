"""``olatbench datasets info|validate|convert``: output, exit codes, one-line errors."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner
from datasets_trees import write_gs3_tree, write_nrhints_tree, write_sssgs_tree

from olatbench.cli import main
from olatbench.datasets import load_scene


def run(*args):
    return CliRunner().invoke(main, ["datasets", *map(str, args)])


def test_group_help_lists_verbs():
    result = run("--help")
    assert result.exit_code == 0
    for verb in ("info", "validate", "convert", "synth", "download", "verify"):
        assert verb in result.output


def test_info_on_one_scene_and_on_a_folder_of_scenes(tmp_path):
    write_nrhints_tree(tmp_path / "Cat_on_Decor", n_path=2)
    write_gs3_tree(tmp_path / "Lego")
    write_sssgs_tree(tmp_path / "bunny_small", share_first=True)
    one = run("info", tmp_path / "Lego")
    assert (
        one.exit_code == 0 and "Lego  (gs3" in one.output and "linear, premultiplied" in one.output
    )
    everything = run("info", tmp_path, "--json")
    assert everything.exit_code == 0
    summaries = json.loads(everything.output)
    assert [s["scene"] for s in summaries] == ["CatSmall", "Lego", "Bunny"]
    assert summaries[0]["splits"] == {"train": 4, "test": 2, "path": 2}
    assert summaries[0]["lights"]["distinct_positions"] == 8
    assert summaries[2]["metadata"]["shared_images"] == 1
    assert summaries[1]["lights"]["distance_to_origin"] == pytest.approx([5.0, 5.0])


def test_info_takes_several_paths(tmp_path):
    write_gs3_tree(tmp_path / "Lego")
    write_sssgs_tree(tmp_path / "more" / "bunny_small", share_first=True)
    result = run("info", tmp_path / "Lego", tmp_path / "more", tmp_path / "Lego", "--json")
    assert result.exit_code == 0, result.output
    assert [s["scene"] for s in json.loads(result.output)] == ["Lego", "Bunny"]  # each scene once


def test_validate_ok_and_failing(tmp_path):
    write_nrhints_tree(tmp_path / "a")
    ok = run("validate", tmp_path / "a")
    assert ok.exit_code == 0 and "errors" in ok.output
    (tmp_path / "a/test/001.png").write_bytes(b"garbage")
    bad = run("validate", tmp_path / "a", "--json")
    assert bad.exit_code == 1
    report = json.loads(bad.output)[0]
    assert report["errors"] == 1 and report["issues"][0]["frame"] == "001"
    text = run("validate", tmp_path / "a")
    assert text.exit_code == 1 and "001.png" in text.output


def test_convert(tmp_path):
    write_gs3_tree(tmp_path / "Lego", n_path=2)
    result = run("convert", tmp_path / "Lego", tmp_path / "out", "--to", "sssgs")
    assert result.exit_code == 0, result.output
    assert "dropping the 2 camera-path frames" in result.output
    assert load_scene(tmp_path / "out").format == "sssgs"
    again = run("convert", tmp_path / "Lego", tmp_path / "out", "--to", "sssgs")
    # a usage error: --overwrite or elsewhere
    assert again.exit_code == 2 and "already exists" in again.output


def test_dataset_errors_are_one_line_without_traceback(tmp_path):
    write_nrhints_tree(tmp_path / "a")
    (tmp_path / "a/transforms_train.json").write_text("{broken")
    for args in (
        ("info", tmp_path / "a"),
        ("convert", tmp_path / "a", tmp_path / "b", "--to", "gs3"),
    ):
        result = run(*args)
        assert result.exit_code == 1
        assert "Traceback" not in result.output
        assert "transforms_train.json: malformed JSON" in result.output
        assert "olatbench datasets validate" in result.output  # suggests the next command
    assert run("info", tmp_path).exit_code == 1  # the folder holds a broken scene (a/)
    (tmp_path / "empty").mkdir()
    assert run("info", tmp_path / "empty").exit_code == 2  # no scene at all: a usage error


def test_info_keeps_going_past_a_broken_scene(tmp_path):
    write_nrhints_tree(tmp_path / "Pixiu")
    write_nrhints_tree(tmp_path / "Fish")
    (tmp_path / "Fish/transforms_test.json").write_text("{")
    result = run("info", tmp_path)
    assert result.exit_code == 1 and "Pixiu  (nrhints" in result.output
    assert (
        "Fish/transforms_test.json: malformed JSON" in result.output
        and "Traceback" not in result.output
    )


def test_validate_reports_unreadable_json_as_an_error(tmp_path):
    write_sssgs_tree(tmp_path / "s")
    (tmp_path / "s/transforms_test.json").write_text("[1]")
    result = run("validate", tmp_path / "s", "--json")
    assert result.exit_code == 1 and "JSON object" in result.output
