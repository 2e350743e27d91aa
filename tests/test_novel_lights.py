"""The mini suite's ground truth under new illumination
(#57 item 3, `olatbench.datasets.novel_lights`): the packaged conditions, installed from the package
with every byte checked, the layout and `load_condition`, a scene of one's own made with
``datasets synth --lights``, and (slow) one condition rendered again against the packaged bytes."""

from __future__ import annotations

import hashlib
import json
import logging
import shutil
import tarfile

import numpy as np
import pytest
from click.testing import CliRunner

import olatbench.datasets.novel_lights as novel_lights
import olatbench.datasets.synth.reference as reference_module
from olatbench.cli import main
from olatbench.datasets import load_scene
from olatbench.datasets.colour import srgb_to_linear
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.images import read_image, round_half_mantissa, write_image
from olatbench.datasets.lighting import (
    EnvironmentMap,
    RectLight,
    lighting_from_dict,
    lighting_to_dict,
    read_lighting,
)
from olatbench.datasets.novel_lights import (
    CONDITIONS,
    condition_lighting,
    ensure_novel_lights,
    lighting_file,
    load_condition,
)
from olatbench.datasets.records import PointLight
from olatbench.datasets.synth.mini import MANIFEST, ensure_mini_suite, mini_recipes, scene_is_valid
from olatbench.datasets.synth.reference import NOVEL_LIGHTS, archive_path, load_reference


def _hashes(folder):
    """sha256 of every file below ``folder`` but the manifest, computed here
    (not by the code under test)."""
    return {
        path.relative_to(folder).as_posix(): hashlib.sha256(path.read_bytes()).hexdigest()
        for path in folder.rglob("*")
        if path.is_file() and path.name != MANIFEST
    }


def _no_rendering(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("the ground truth was rendered instead of installed")

    monkeypatch.setattr(novel_lights, "render_novel_lights", refuse)
    monkeypatch.setattr(novel_lights, "render_condition", refuse)


@pytest.fixture()
def mini_scene(tmp_path, monkeypatch):
    """The installed mini scene ``aniso_metal`` (the packaged reference), without its novel lights
    yet."""
    _no_rendering(monkeypatch)
    return (
        ensure_mini_suite(tmp_path / "mini", progress=False, scenes=["aniso_metal"]) / "aniso_metal"
    )


def test_rounding_half_mantissas_is_exact_in_a_half_exr_and_bounded(tmp_path):
    values = np.random.default_rng(0).lognormal(-1.0, 2.0, size=(40, 50, 3)).astype(np.float32)
    values[0, 0] = [0.0, 1.997, 65000.0]  # zero, a carry into the exponent, near half's largest
    rounded = round_half_mantissa(values, 6)
    write_image(tmp_path / "r.exr", rounded, "half")
    np.testing.assert_array_equal(read_image(tmp_path / "r.exr"), rounded)  # written exactly
    assert rounded[0, 0, 0] == 0.0 and rounded[0, 0, 1] == 2.0
    normal = values > 2.0**-14  # half's normal range: relative error ≤ 2^-7 (+ half's own 2^-11)
    assert np.max(np.abs(rounded - values)[normal] / values[normal]) <= 2.0**-7 + 2.0**-11
    # fewer distinct values
    assert len(np.unique(rounded)) < len(np.unique(values.astype(np.float16)))
    np.testing.assert_array_equal(
        round_half_mantissa(values, 10), values.astype(np.float16).astype(np.float32)
    )
    with pytest.raises(ValueError, match="0 to 10 mantissa bits"):
        round_half_mantissa(values, 11)
    with pytest.raises(ValueError, match="non-finite or too large"):
        round_half_mantissa(np.float32([65500.0]), 3)


def test_the_conditions_are_lighting_files_that_round_trip():
    packaged = sorted(
        path.stem for path in (reference_module.reference_root() / "novel_lights").glob("*.json")
    )
    assert sorted(CONDITIONS) == packaged
    kinds = {}
    for condition in CONDITIONS:
        lighting = read_lighting(lighting_file(condition))
        data = lighting_to_dict(lighting)
        assert lighting_to_dict(lighting_from_dict(json.loads(json.dumps(data)))) == data
        kinds[condition] = [type(source) for source in lighting.sources]
    assert kinds["two_lights"] == [PointLight] * 2 and kinds["three_lights"] == [PointLight] * 3
    # drawn as points
    assert kinds["area"] == [RectLight] and len(condition_lighting("area").sample()) > 1
    for name in ("studio", "sky"):
        (source,) = condition_lighting(name).sources
        assert isinstance(source, EnvironmentMap) and source.source == name
    colours = [light.intensity for light in condition_lighting("two_lights").sources]
    # two colours
    assert not np.allclose(colours[0] / colours[0].sum(), colours[1] / colours[1].sum())
    with pytest.raises(KeyError, match="conditions: two_lights"):
        lighting_file("moonlight")


def test_the_package_is_installed_with_every_byte_checked_and_kept_apart_from_the_scene(mini_scene):
    recipe = mini_recipes()["aniso_metal"]
    folder = ensure_novel_lights(mini_scene)
    assert folder == mini_scene / "novel_lights"
    assert _hashes(folder) == load_reference(package=NOVEL_LIGHTS)["scenes"]["aniso_metal"]["files"]
    test_ids = [frame.frame_id for frame in load_scene(mini_scene).split("test")]
    for condition in CONDITIONS:
        names = sorted(path.name for path in (folder / condition).iterdir())
        assert names == sorted(
            ["lighting.json", "lit.json", *(f"{frame_id}.exr" for frame_id in test_ids)]
        )
        assert lighting_to_dict(
            read_lighting(folder / condition / "lighting.json")
        ) == lighting_to_dict(condition_lighting(condition))
    # the scene's own manifest ignores novel_lights/
    assert scene_is_valid(mini_scene, recipe) == (True, "ok")
    installed = {path: path.stat().st_mtime_ns for path in folder.rglob("*")}
    assert ensure_novel_lights(mini_scene) == folder
    # checked, not reinstalled
    assert {path: path.stat().st_mtime_ns for path in folder.rglob("*")} == installed
    ensure_mini_suite(mini_scene.parent, progress=False, scenes=["aniso_metal"])
    assert (folder / "studio").is_dir()  # the scene was kept: its novel lights with it


def test_load_condition_gives_the_lighting_and_the_test_frames_in_order(mini_scene):
    condition = load_condition(mini_scene, "studio")
    assert condition.name == "studio"
    assert lighting_to_dict(condition.lighting) == lighting_to_dict(condition_lighting("studio"))
    assert list(condition.frames) == [
        frame.frame_id for frame in load_scene(mini_scene).split("test")
    ]
    image = read_image(condition.frames["r_0007"])
    assert image.shape == (80, 80, 4) and np.all(np.isfinite(image))
    # straight alpha: coverage
    assert set(np.unique(image[..., 3])) >= {0.0, 1.0} and image[..., 3].max() <= 1.0
    assert image[..., :3][image[..., 3] > 0.5].mean() > 0.05  # lit
    with pytest.raises(
        DatasetError, match=r"no condition 'moonlight' here; conditions: area, sky, studio"
    ):
        load_condition(mini_scene, "moonlight")


def test_the_packaged_conditions_are_exposed_like_the_olat_test_images(mini_scene, tmp_path):
    """Each condition's covered pixels are, on average, within a factor 2 of the OLAT test images'
    (linear), with few clipped values and no near-black views."""
    for scene_name in ("aniso_metal", "diffuse_shadow", "translucent"):
        scene = (
            ensure_mini_suite(mini_scene.parent, progress=False, scenes=[scene_name]) / scene_name
        )
        olat = []
        for frame in load_scene(scene).split("test"):
            pixels = read_image(frame.image_path)
            olat.append(srgb_to_linear(pixels[..., :3])[pixels[..., 3] > 0.5].mean())
        for name in CONDITIONS:
            means, clipped = [], []
            for path in load_condition(scene, name).frames.values():
                image = read_image(path)
                covered = image[..., :3][image[..., 3] > 0.5]
                means.append(covered.mean())
                clipped.append(np.mean(covered.max(axis=-1) >= 1.0))
            ratio = np.mean(means) / np.mean(olat)
            assert 0.5 < ratio < 2.0, (scene_name, name, ratio)
            assert min(means) > 0.05 and np.mean(clipped) < 0.1, (
                scene_name,
                name,
                min(means),
                np.mean(clipped),
            )


def test_damaged_files_are_replaced_and_a_damaged_package_is_refused_naming_the_file(
    mini_scene, tmp_path, monkeypatch, caplog
):
    folder = ensure_novel_lights(mini_scene)
    expected = _hashes(folder)
    # one byte flipped in an installed image
    with open(folder / "sky" / "r_0003.exr", "r+b") as handle:
        handle.seek(200)
        byte = handle.read(1)
        handle.seek(200)
        handle.write(bytes([byte[0] ^ 0xFF]))
    with caplog.at_level(logging.WARNING):
        ensure_novel_lights(mini_scene)
    assert (
        "sky/r_0003.exr" in caplog.text
        and "replacing" in caplog.text
        and _hashes(folder) == expected
    )

    packaged = tmp_path / "package"
    shutil.copytree(reference_module.reference_root(), packaged)
    archive = archive_path("aniso_metal", packaged, NOVEL_LIGHTS)
    unpacked = tmp_path / "unpacked"
    with tarfile.open(archive) as bundle:
        bundle.extractall(unpacked, filter="data")
        names = bundle.getnames()
    with open(unpacked / "studio" / "r_0011.exr", "r+b") as handle:
        handle.seek(300)
        byte = handle.read(1)
        handle.seek(300)
        handle.write(bytes([byte[0] ^ 0x01]))
    with tarfile.open(archive, "w:xz") as bundle:
        for name in names:
            bundle.add(unpacked / name, arcname=name)
    monkeypatch.setattr(reference_module, "reference_root", lambda: packaged)
    shutil.rmtree(folder)
    with pytest.raises(
        DatasetError,
        match=r"aniso_metal\.tar\.xz: .*does not match the hashes in "
        r"novel_lights_reference\.json.*studio/r_0011\.exr",
    ):
        ensure_novel_lights(mini_scene)
    assert (
        not (mini_scene / "novel_lights").exists()
        and not (mini_scene / ".novel_lights.partial").exists()
    )


def test_datasets_synth_mini_installs_and_compares_the_novel_lights(tmp_path, monkeypatch):
    _no_rendering(monkeypatch)
    result = CliRunner().invoke(
        main, ["datasets", "synth", "--mini", "-o", str(tmp_path / "mini"), "-q"]
    )
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[3:6] == [
        f"mini/{scene}/novel_lights: identical to the reference (Mitsuba 3.9.1 scalar_rgb)"
        for scene in ("diffuse_shadow", "aniso_metal", "translucent")
    ]
    info = CliRunner().invoke(main, ["datasets", "info", str(tmp_path / "mini" / "translucent")])
    assert (
        info.exit_code == 0
        and "novel lights: two_lights, three_lights, area, studio, sky" in info.output
    )


@pytest.mark.usefixtures("mitsuba_scalar_variant")
def test_a_scene_of_ones_own_gets_conditions_from_datasets_synth_lights(tmp_path):
    pytest.importorskip("mitsuba")
    scene = tmp_path / "mine"
    options = [
        "--recipe",
        "diffuse_shadow",
        "--resolution",
        "24",
        "--spp",
        "4",
        "--train",
        "2",
        "--test",
        "3",
    ]
    made = CliRunner().invoke(
        main, ["datasets", "synth", *options, "--no-geometry", "-o", str(scene), "-q"]
    )
    assert made.exit_code == 0, made.output
    with pytest.raises(
        DatasetError, match=r"mine/novel_lights: no ground truth under new illumination"
    ):
        ensure_novel_lights(scene)
    lit = CliRunner().invoke(
        main,
        [
            "datasets",
            "synth",
            *options,
            "--lights",
            str(lighting_file("two_lights")),
            "-o",
            str(scene / "novel_lights" / "two"),
            "-q",
        ],
    )
    assert lit.exit_code == 0, lit.output
    condition = load_condition(scene, "two")
    assert list(condition.frames) == [frame.frame_id for frame in load_scene(scene).split("test")]
    assert lighting_to_dict(condition.lighting) == lighting_to_dict(
        condition_lighting("two_lights")
    )
    assert read_image(condition.frames["r_0002"]).shape == (24, 24, 4)
    record = json.loads((scene / "novel_lights" / "two" / "lit.json").read_text())
    del record["frames"]["r_0001"]
    (scene / "novel_lights" / "two" / "lit.json").write_text(json.dumps(record))
    with pytest.raises(
        DatasetError,
        match=r"two/lit\.json, key 'frames': the frames are not the scene's test frames",
    ):
        load_condition(scene, "two")


@pytest.mark.slow
@pytest.mark.usefixtures("mitsuba_scalar_variant")
def test_rendering_a_condition_again_gives_the_packaged_bytes(tmp_path):
    """One condition of one scene rendered here as the package's were: the same bytes (the mini
    suite's pinned variant is deterministic on one machine); elsewhere the comparison says how far
    (docs/relighting.md)."""
    pytest.importorskip("mitsuba")
    folder = tmp_path / "diffuse_shadow" / "novel_lights"
    novel_lights.render_condition(
        "diffuse_shadow", "two_lights", folder / "two_lights", progress=False
    )
    expected = {
        path: digest
        for path, digest in load_reference(package=NOVEL_LIGHTS)["scenes"]["diffuse_shadow"][
            "files"
        ].items()
        if path.startswith("two_lights/")
    }
    comparison = reference_module.compare_scene(
        folder, "diffuse_shadow", _hashes(folder), package=NOVEL_LIGHTS
    )
    assert _hashes(folder) == expected, comparison.summary(load_reference(package=NOVEL_LIGHTS))
