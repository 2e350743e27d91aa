"""Rendering the mini suite here against its packaged reference: byte identity, pixel differences,
the variant pin, the runner's flag (installing the reference renders:
tests/test_mini_install.py)."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from olatbench.datasets.synth import backend
from olatbench.datasets.synth.mini import (
    MANIFEST,
    MINI_VARIANT,
    compare_with_reference,
    data_matches_reference,
    ensure_mini_suite,
    file_hashes,
)
from olatbench.datasets.synth.recipe import RECIPES
from olatbench.datasets.synth.reference import (
    archive_path,
    compare_scene,
    load_reference,
    write_reference,
)

pytest.importorskip("mitsuba")


@pytest.fixture()
def tiny_suite(tmp_path, monkeypatch):
    """A one-scene 'mini' suite of a tiny diffuse_shadow recipe and a reference made from it."""
    monkeypatch.delenv(backend.VARIANT_ENV, raising=False)
    recipe = RECIPES["diffuse_shadow"].with_overrides(
        resolution=(24, 24), spp=4, train=3, test=2, max_depth=2
    )
    root = ensure_mini_suite(tmp_path / "mini", progress=False, recipes={"diffuse_shadow": recipe})
    files = json.loads((root / "diffuse_shadow" / MANIFEST).read_text())["files"]
    write_reference(
        root,
        {"diffuse_shadow": files},
        {
            "generator_version": 0,
            "mitsuba_version": "x",
            "mitsuba_variant": MINI_VARIANT,
            "made_on": "test",
        },
        out=tmp_path / "reference",
    )
    return root / "diffuse_shadow", tmp_path / "reference"


def test_identical_scene_and_rendering_again_gives_the_same_bytes(tiny_suite, tmp_path):
    scene, reference_dir = tiny_suite
    reference = load_reference(reference_dir)
    assert archive_path("diffuse_shadow", reference_dir).is_file()
    comparison = compare_scene(
        scene, "diffuse_shadow", file_hashes(scene), reference, root=reference_dir
    )
    assert comparison.identical and "identical to the reference" in comparison.summary(reference)
    again = ensure_mini_suite(
        tmp_path / "again",
        progress=False,
        recipes={
            "diffuse_shadow": RECIPES["diffuse_shadow"].with_overrides(
                resolution=(24, 24), spp=4, train=3, test=2, max_depth=2
            )
        },
    )
    assert compare_scene(
        again / "diffuse_shadow",
        "diffuse_shadow",
        file_hashes(again / "diffuse_shadow"),
        reference,
        root=reference_dir,
    ).identical  # deterministic on one machine


def test_differences_name_the_files_and_measure_the_pixels(tiny_suite):
    scene, reference_dir = tiny_suite
    reference = load_reference(reference_dir)
    image = cv2.imread(str(scene / "test/r_0001.png"), cv2.IMREAD_UNCHANGED)
    image[5, 7, 0] = np.uint8(
        min(int(image[5, 7, 0]) + 51, 255) if image[5, 7, 0] < 200 else image[5, 7, 0] - 51
    )
    cv2.imwrite(str(scene / "test/r_0001.png"), image)
    (scene / "train/r_0002.png").unlink()
    comparison = compare_scene(
        scene, "diffuse_shadow", file_hashes(scene), reference, root=reference_dir
    )
    assert not comparison.identical
    assert comparison.differing == ["test/r_0001.png"] and comparison.missing == [
        "train/r_0002.png"
    ]
    # every image present in both (3 train + 2 test, one missing), not a sample
    assert comparison.images == 4
    (difference,) = comparison.pixels
    assert difference.max_abs == pytest.approx(51 / 255, abs=1e-6)
    assert difference.mean_abs == pytest.approx(51 / 255 / image.size, rel=1e-4)
    summary = comparison.summary(reference)
    assert "NOT identical" in summary and "1 differ" in summary and "1 missing" in summary
    assert "1 of 4 images compared differ" in summary and "max |Δ| = 0.2 " in summary
    # one pixel: still not 0.00000
    assert f"mean |Δ| = {51 / 255 / image.size / 4:.3g} over all 4" in summary


def test_a_difference_outside_the_images_says_the_images_are_identical(tiny_suite):
    scene, reference_dir = tiny_suite
    reference = load_reference(reference_dir)
    with open(scene / "geometry/test/r_0000.exr", "ab") as handle:
        handle.write(b"\0")
    comparison = compare_scene(
        scene, "diffuse_shadow", file_hashes(scene), reference, root=reference_dir
    )
    assert comparison.differing == ["geometry/test/r_0000.exr"] and comparison.pixels == []
    assert comparison.summary(reference).endswith("its 5 images are identical")


def test_mini_renders_with_the_pinned_variant_unless_the_environment_says_otherwise(monkeypatch):
    monkeypatch.delenv(backend.VARIANT_ENV, raising=False)
    monkeypatch.setattr(backend, "probe_variant", lambda: "llvm_ad_rgb")
    assert backend.active_variant() == "llvm_ad_rgb"
    with backend.pinned_variant(MINI_VARIANT):
        assert backend.active_variant() == "scalar_rgb"
        monkeypatch.setenv(backend.VARIANT_ENV, "llvm_ad_rgb")
        # an explicit choice wins, and shows in the comparison
        assert backend.active_variant() == "llvm_ad_rgb"


def test_data_matches_reference_reads_the_manifest(tmp_path):
    reference = load_reference()
    scene = tmp_path / "aniso_metal"
    scene.mkdir()
    (scene / MANIFEST).write_text(
        json.dumps({"files": reference["scenes"]["aniso_metal"]["files"]})
    )
    assert data_matches_reference(scene) is True  # hashes only: no image is read when all match
    changed = dict(
        reference["scenes"]["aniso_metal"]["files"], **{"transforms_train.json": "0" * 64}
    )
    (scene / MANIFEST).write_text(json.dumps({"files": changed}))
    assert data_matches_reference(scene) is False
    assert compare_with_reference(scene).differing == ["transforms_train.json"]
    other = tmp_path / "Pixiu"
    other.mkdir()
    assert data_matches_reference(other) is None  # not a mini scene


RENDER_TINY = """
import json, sys
from pathlib import Path
from olatbench.datasets.synth.mini import MANIFEST, ensure_mini_suite
from olatbench.datasets.synth.recipe import RECIPES
recipe = RECIPES["diffuse_shadow"].with_overrides(resolution=(24, 24), spp=4, train=3, test=2, max_depth=2)
root = ensure_mini_suite(Path(sys.argv[1]), progress=False, recipes={"diffuse_shadow": recipe})
print(json.dumps(json.loads((root / "diffuse_shadow" / MANIFEST).read_text())["files"]))
"""  # noqa: E501


def test_the_bytes_do_not_depend_on_the_cpus_blas_kernel(tmp_path, monkeypatch):
    """The same tiny scene (blob mesh, checker texture: every generator path) under OpenBLAS's
    Haswell (FMA) and Prescott (SSE3) kernels is byte-identical: the generator never calls BLAS (or
    numpy's CPU-dispatched transcendentals, which this AVX2 machine cannot switch;
    `olatbench.datasets.portable`). With `@` in the blob's displacement or `np.linalg.norm` in
    `look_at`, geometry and images differed here."""
    import subprocess
    import sys

    monkeypatch.delenv(backend.VARIANT_ENV, raising=False)
    manifests = []
    for core in ("Haswell", "Prescott"):
        env = {**__import__("os").environ, "OPENBLAS_CORETYPE": core}
        out = subprocess.run(
            [sys.executable, "-c", RENDER_TINY, str(tmp_path / core)],
            env=env,
            check=True,
            capture_output=True,
            text=True,
        ).stdout
        manifests.append(json.loads(out.strip().splitlines()[-1]))
    assert manifests[0] == manifests[1]


def test_rendering_the_builtin_suite_says_whether_it_matches_the_reference(
    tmp_path, monkeypatch, capsys
):
    import olatbench.datasets.synth.mini as mini

    rendered = []
    monkeypatch.setattr(
        mini, "scene_is_valid", lambda folder, recipe: (folder.name != "translucent", "missing")
    )
    monkeypatch.setattr(
        mini, "render_mini_scene", lambda root, name, recipe, progress: rendered.append(name)
    )
    monkeypatch.setattr(
        mini, "compare_with_reference", lambda folder, reference: _Said(folder.name)
    )
    mini.ensure_mini_suite(tmp_path, progress=True, render=True)
    assert rendered == ["translucent"]
    # said for the scene rendered now
    assert capsys.readouterr().err.splitlines() == ["translucent: identical"]


class _Said:
    identical = True

    def __init__(self, name):
        self.name = name

    def summary(self, reference):
        return f"{self.name}: identical"
