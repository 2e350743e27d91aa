"""Procedural meshes, recipes and rigs of the scene generator (numpy only, no Mitsuba)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from waiting import BACKSTOP_SECONDS

from olatbench.datasets.cameras import project_points
from olatbench.datasets.synth import meshes
from olatbench.datasets.synth.recipe import RECIPES, Recipe, get_recipe
from olatbench.datasets.synth.rigs import band_directions, make_rig


def signed_volume(mesh: meshes.TriangleMesh) -> float:
    corners = mesh.vertices[mesh.faces]
    return float(
        np.einsum("ij,ij->i", corners[:, 0], np.cross(corners[:, 1], corners[:, 2])).sum() / 6.0
    )


@pytest.mark.parametrize("name", sorted(meshes.PROCEDURAL_SHAPES))
def test_procedural_meshes_are_closed_outward_and_smooth(name):
    mesh = meshes.procedural_mesh(name)
    assert meshes.is_watertight(mesh)
    assert signed_volume(mesh) > 0  # faces wind counter-clockwise seen from outside
    assert np.allclose(np.linalg.norm(mesh.normals, axis=1), 1.0)
    # vertex normals agree with the adjacent face normals (outward, smooth)
    corners = mesh.vertices[mesh.faces]
    face_normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    face_normals /= np.linalg.norm(face_normals, axis=1, keepdims=True)
    agreement = np.einsum("ij,ij->i", face_normals, mesh.normals[mesh.faces[:, 0]])
    assert np.percentile(agreement, 1) > 0.9
    assert mesh.uvs.min() >= 0.0 and mesh.uvs.max() <= 1.0


def test_analytic_volumes_match_closed_forms():
    assert signed_volume(meshes.sphere(96)) == pytest.approx(4.0 / 3.0 * np.pi, rel=2e-3)
    assert signed_volume(meshes.torus(96, 1.0, 0.4)) == pytest.approx(
        2 * np.pi**2 * 1.0 * 0.4**2, rel=2e-3
    )
    # rounded box: box minus the edge and corner deficits
    h, r = np.array([1.0, 0.8, 0.6]), 0.25
    inner = h - r
    expected = (
        8 * np.prod(inner)
        + 8 * r * (inner[0] * inner[1] + inner[1] * inner[2] + inner[0] * inner[2])
        + 2 * np.pi * r**2 * inner.sum()
        + 4.0 / 3.0 * np.pi * r**3
    )
    assert signed_volume(meshes.rounded_box(128)) == pytest.approx(expected, rel=5e-3)


def test_watertight_check_detects_a_hole():
    mesh = meshes.sphere(16)
    holed = meshes.TriangleMesh(mesh.vertices, mesh.faces[1:], mesh.uvs, mesh.normals)
    assert not meshes.is_watertight(holed)


def test_place_on_ground_gives_unit_bounding_sphere_on_z0():
    placed = meshes.place_on_ground(meshes.torus())
    centre, radius = placed.bounding_sphere()
    assert radius == pytest.approx(1.0)
    assert placed.vertices[:, 2].min() == pytest.approx(1e-3)
    assert np.allclose(centre[:2], 0.0)


def test_recipe_round_trips_through_json_and_names_bad_keys(tmp_path):
    recipe = RECIPES["translucent"]
    path = tmp_path / "mine.json"
    path.write_text(json.dumps(recipe.to_dict()))
    assert get_recipe(path) == recipe
    path.write_text(
        json.dumps({"shape": "torus", "material": {"kind": "diffuse", "albdo": [1, 1, 1]}})
    )
    with pytest.raises(ValueError, match="albdo"):
        get_recipe(path)
    with pytest.raises(ValueError, match="resolution"):
        Recipe(name="x", resolution=(2, 2)).validate()
    with pytest.raises(ValueError, match="not a built-in"):
        get_recipe("no_such_recipe")


def test_band_directions_cover_the_band_evenly():
    directions = band_directions(400, (10.0, 60.0), np.random.default_rng(0))
    elevation = np.degrees(np.arcsin(directions[:, 2]))
    assert elevation.min() >= 10.0 and elevation.max() <= 60.0
    assert np.allclose(np.linalg.norm(directions, axis=1), 1.0)
    # area-uniform: half of the band's area lies below the median of sin(elevation)
    median_z = 0.5 * (np.sin(np.radians(10)) + np.sin(np.radians(60)))
    assert np.mean(directions[:, 2] < median_z) == pytest.approx(0.5, abs=0.02)


@pytest.mark.parametrize("novel_views", [False, True])
def test_rig_lights_are_disjoint_cameras_look_at_the_object(novel_views):
    recipe = RECIPES["diffuse_shadow"].with_overrides(train=30, test=8, novel_views=novel_views)
    centre = np.array([0.0, 0.0, 0.6])
    rig = make_rig(recipe, centre)
    train, test = rig.frames["train"], rig.frames["test"]
    assert (len(train), len(test)) == (30, 8)
    train_lights = np.array([light.position for _, light in train])
    test_lights = np.array([light.position for _, light in test])
    gaps = np.linalg.norm(test_lights[:, None] - train_lights[None], axis=-1)
    assert gaps.min() > 0.1  # every test light is new
    for camera, light in train + test:
        uv, depth = project_points(centre[None], camera.K, camera.c2w)
        assert np.allclose(uv[0], [camera.width / 2, camera.height / 2])
        assert depth[0] == pytest.approx(recipe.cameras.radius)
        assert np.linalg.norm(light.position - camera.position) > camera.near
    train_positions = {tuple(np.round(camera.position, 9)) for camera, _ in train}
    seen = [tuple(np.round(camera.position, 9)) in train_positions for camera, _ in test]
    assert all(seen) != novel_views and (any(seen) != novel_views)
    again = make_rig(recipe, centre)
    assert np.array_equal(again.frames["test"][3][1].position, test[3][1].position)


def test_package_imports_without_mitsuba_and_the_cli_says_how_to_install():
    script = """
import sys
class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in ('mitsuba', 'drjit'):
            raise ImportError('No module named ' + repr(name))
sys.meta_path.insert(0, Block())
import olatbench.datasets.synth.mini, olatbench.datasets.synth.generate, olatbench.cli.synth
from click.testing import CliRunner
from olatbench.cli.synth import synth
result = CliRunner().invoke(synth, ['--recipe', 'aniso_metal', '--out', 'never-written'])
assert 'mitsuba' not in sys.modules
print(result.exit_code, result.output)
"""
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=BACKSTOP_SECONDS
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("1 ")
    assert "pip install 'olatbench[synth]'" in result.stdout


@pytest.mark.parametrize("name", ["checker", "marble"])
def test_procedural_textures_are_seamless_in_u_and_bounded(name):
    from olatbench.datasets.synth.textures import procedural_texture

    texture = procedural_texture(name, (0.7, 0.4, 0.2), size=128, scale=8.0)
    assert texture.shape == (128, 128, 3) and texture.dtype == np.float32
    assert texture.min() >= 0.02 and texture.max() <= 0.9
    seam = np.abs(texture[:, 0] - texture[:, -1]).mean()
    neighbours = np.abs(texture[:, 1:] - texture[:, :-1]).mean()
    middle = np.abs(texture[:, 64] - texture[:, 63]).mean()  # u = 0.5: a tile edge of the checker
    # wrapping around u looks like any other place of the pattern
    assert seam < 1.5 * middle + 3 * neighbours
    assert texture.std() > 0.05  # an actual pattern
