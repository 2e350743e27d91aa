"""Ground truth under a lighting (#57, `olatbench.datasets.synth.lit`): a recipe's test cameras
rendered with Mitsuba under a lighting's emitters, at tiny resolution with ``scalar_rgb``."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("mitsuba")

from click.testing import CliRunner

from olatbench.datasets import load_scene
from olatbench.datasets.images import read_image
from olatbench.datasets.lighting import (
    BUILT_IN_MAPS,
    DirectionalLight,
    EnvironmentMap,
    Lighting,
    SphereLight,
)
from olatbench.datasets.lighting.envmap import map_axes, pixel_directions, pixel_solid_angles
from olatbench.datasets.records import PointLight
from olatbench.datasets.synth.lit import LitRenderer, emitters
from olatbench.datasets.synth.recipe import RECIPES
from olatbench.datasets.synth.render import SceneRenderer
from olatbench.datasets.synth.rigs import make_rig

pytestmark = pytest.mark.usefixtures("mitsuba_scalar_variant")


def tiny(**overrides):
    return RECIPES["diffuse_shadow"].with_overrides(
        **{"resolution": (24, 24), "spp": 16, "train": 2, "test": 2, "max_depth": 2, **overrides}
    )


def test_a_lighting_of_one_point_light_renders_the_olat_frame():
    recipe = tiny()
    olat = SceneRenderer(recipe)
    camera, light = make_rig(recipe, olat.mesh.bounding_sphere()[0]).frames["test"][0]
    lit = LitRenderer(recipe, Lighting((PointLight(light.position, light.intensity, True),)))
    np.testing.assert_allclose(lit.render(camera, 5), olat.render(camera, light, 5), atol=1e-6)


def test_area_lights_are_the_points_the_models_see():
    lighting = Lighting(
        (
            SphereLight(np.array([0.0, 0.0, 4.0]), 0.5, np.full(3, 20.0), 5),
            EnvironmentMap("furnace", samples=3),
            SphereLight(np.zeros(3), 1.0, np.ones(3), 4),
        )
    )
    points = [
        light["position"] for light in emitters(lighting).values() if light["type"] == "point"
    ]
    np.testing.assert_array_equal(
        points, [light.position for light in lighting.sample(np.array([0, 0, 1.0])).points]
    )


def test_an_environment_map_lights_from_where_olatbench_puts_its_radiance(monkeypatch):
    """A map bright in one small patch (rotated 30°) lights the scene as a directional light of the
    same irradiance from the patch's direction in olatbench's convention, and unlike one from the
    mirrored direction."""
    recipe = tiny()
    height, row, col, rotation = 64, 20, 80, 30.0
    radiance = np.zeros((height, 2 * height, 3), dtype=np.float32)
    radiance[row : row + 2, col : col + 2] = 200.0
    theta, phi = pixel_directions(height, 2 * height)
    t, p = (
        (theta[row, 0] + theta[row + 1, 0]) / 2,
        (phi[0, col] + phi[0, col + 1]) / 2 + np.radians(rotation),
    )
    direction = np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)]) @ map_axes(
        np.array([0, 0, 1.0])
    )
    irradiance = np.full(
        3, 200.0 * 2 * pixel_solid_angles(height, 2 * height)[row : row + 2, 0].sum()
    )
    monkeypatch.setitem(BUILT_IN_MAPS, "patch", lambda: radiance.astype(np.float64))
    under_map = LitRenderer(recipe, Lighting((EnvironmentMap("patch", rotation),)))
    camera = make_rig(recipe, under_map.mesh.bounding_sphere()[0]).frames["test"][0][0]
    image = under_map.render(camera, 1)[..., :3]
    right = LitRenderer(recipe, Lighting((DirectionalLight(direction, irradiance),))).render(
        camera, 1
    )[..., :3]
    mirrored = direction * np.array([1.0, -1.0, 1.0])
    wrong = LitRenderer(recipe, Lighting((DirectionalLight(mirrored, irradiance),))).render(
        camera, 1
    )[..., :3]
    assert right.mean() > 0.01
    assert np.abs(image - right).mean() < 0.3 * np.abs(image - wrong).mean()
    assert image.mean() == pytest.approx(right.mean(), rel=0.15)


def test_cli_renders_the_test_cameras_under_a_lighting(tmp_path):
    from olatbench.cli.synth import synth

    (tmp_path / "two.json").write_text(
        json.dumps(
            {
                "lights": [
                    {"type": "point", "position": [0, -3, 4], "intensity": 10},
                    {"type": "directional", "direction": [1, 0, 1], "irradiance": [0.5, 0.4, 0.3]},
                ]
            }
        )
    )
    common = [
        "--recipe",
        "diffuse_shadow",
        "--res",
        "16x12",
        "--spp",
        "2",
        "--train",
        "2",
        "--test",
        "2",
    ]
    result = CliRunner().invoke(
        synth, [*common, "--lights", str(tmp_path / "two.json"), "-o", str(tmp_path / "lit")]
    )
    assert result.exit_code == 0, result.output
    info = json.loads((tmp_path / "lit" / "lit.json").read_text())
    assert sorted(info["frames"]) == ["r_0000", "r_0001"] and len(info["lighting"]["lights"]) == 2
    image = read_image(tmp_path / "lit" / "r_0001.exr")
    assert image.shape == (12, 16, 4) and image[..., :3].max() > 0.0
    # the OLAT scene of the recipe
    scene = CliRunner().invoke(synth, [*common, "-o", str(tmp_path / "scene")])
    assert scene.exit_code == 0, scene.output
    test = load_scene(tmp_path / "scene").split("test")
    # the same cameras, the same ids
    assert [frame.frame_id for frame in test] == sorted(info["frames"])
    for frame in test:
        np.testing.assert_allclose(
            info["frames"][frame.frame_id]["c2w"], frame.camera.c2w, atol=1e-6
        )
    again = CliRunner().invoke(
        synth, [*common, "--lights", str(tmp_path / "two.json"), "-o", str(tmp_path / "lit")]
    )
    assert again.exit_code == 2 and "not empty" in again.output
    (tmp_path / "bad.json").write_text(
        json.dumps({"lights": [{"type": "sphere", "centre": [0, 0, 3]}]})
    )
    bad = CliRunner().invoke(
        synth, [*common, "--lights", str(tmp_path / "bad.json"), "-o", str(tmp_path / "b")]
    )
    assert bad.exit_code == 2 and "bad.json" in bad.output and "lights[0].radius" in bad.output
