"""The mini suite is the packaged reference renders: installed without rendering, every byte
checked."""

from __future__ import annotations

import hashlib
import json
import logging
import shutil
import tarfile

import pytest
from click.testing import CliRunner

import olatbench.datasets.synth.mini as mini
import olatbench.datasets.synth.reference as reference_module
from olatbench.cli import main
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.synth.mini import (
    MANIFEST,
    MINI_SCENES,
    data_matches_reference,
    ensure_mini_suite,
)
from olatbench.datasets.synth.reference import archive_path, load_reference


def _no_rendering(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("the mini suite was rendered instead of installed")

    monkeypatch.setattr(mini, "render_mini_scene", refuse)
    monkeypatch.setattr(mini, "generate", refuse)


def _hashes(folder):
    """sha256 of every file below a scene ``folder`` but the manifest and its ground truth under new
    illumination (``novel_lights/``, installed apart: tests/test_novel_lights.py), computed here
    (not by the code under test)."""
    return {
        path.relative_to(folder).as_posix(): hashlib.sha256(path.read_bytes()).hexdigest()
        for path in folder.rglob("*")
        if path.is_file()
        and path.name != MANIFEST
        and path.relative_to(folder).parts[0] != "novel_lights"
    }


def test_datasets_synth_mini_installs_the_reference_bytes_and_says_so(tmp_path, monkeypatch):
    _no_rendering(monkeypatch)
    result = CliRunner().invoke(
        main, ["datasets", "synth", "--mini", "-o", str(tmp_path / "mini"), "-q"]
    )
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[:3] == [
        f"mini/{scene}: identical to the reference (Mitsuba 3.9.1 scalar_rgb)"
        for scene in MINI_SCENES
    ]
    reference = load_reference()
    for scene in MINI_SCENES:
        installed = _hashes(tmp_path / "mini" / scene)
        assert installed == reference["scenes"][scene]["files"] and len(installed) == 243
        assert data_matches_reference(tmp_path / "mini" / scene) is True
    again = CliRunner().invoke(
        main, ["datasets", "synth", "--mini", "-o", str(tmp_path / "mini"), "-q"]
    )
    assert again.output == result.output  # verified, not installed again


def test_a_damaged_or_locally_rendered_scene_is_replaced_by_the_reference(
    tmp_path, monkeypatch, caplog
):
    _no_rendering(monkeypatch)
    root = ensure_mini_suite(tmp_path / "mini", progress=False, scenes=["aniso_metal"])
    scene = root / "aniso_metal"
    expected = load_reference()["scenes"]["aniso_metal"]["files"]
    (scene / "test/r_0003.png").write_bytes(b"not a png")  # damaged: the manifest no longer matches
    with caplog.at_level(logging.WARNING):
        ensure_mini_suite(root, progress=False, scenes=["aniso_metal"])
    assert "replacing" in caplog.text and _hashes(scene) == expected
    # a scene rendered here: consistent with its own manifest, but not the reference's bytes
    (scene / "train/r_0000.png").write_bytes(b"rendered elsewhere")
    manifest = json.loads((scene / MANIFEST).read_text())
    manifest["files"] = _hashes(scene)
    (scene / MANIFEST).write_text(json.dumps(manifest))
    assert mini.scene_is_valid(scene, mini.mini_recipes()["aniso_metal"]) == (True, "ok")
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        ensure_mini_suite(root, progress=False, scenes=["aniso_metal"])
    assert "not the reference's bytes" in caplog.text and _hashes(scene) == expected


def test_an_archive_whose_bytes_differ_from_the_hashes_is_refused(tmp_path, monkeypatch):
    _no_rendering(monkeypatch)
    packaged = tmp_path / "package"
    shutil.copytree(reference_module.reference_root(), packaged)
    unpacked = tmp_path / "unpacked"
    with tarfile.open(archive_path("translucent", packaged)) as bundle:
        bundle.extractall(unpacked, filter="data")
        names = bundle.getnames()
    with open(unpacked / "test/r_0002.png", "ab") as handle:
        handle.write(b"\0")
    with tarfile.open(archive_path("translucent", packaged), "w:xz") as bundle:
        for name in names:
            bundle.add(unpacked / name, arcname=name)
    monkeypatch.setattr(reference_module, "reference_root", lambda: packaged)
    with pytest.raises(
        DatasetError, match=r"translucent\.tar\.xz: .*does not match the hashes.*test/r_0002\.png"
    ):
        ensure_mini_suite(tmp_path / "mini", progress=False, scenes=["translucent"])
    # no scene, no partial folder
    assert [path.name for path in (tmp_path / "mini").iterdir()] == [".lock"]
