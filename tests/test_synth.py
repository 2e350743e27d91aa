"""Rendering with Mitsuba: camera convention, closed-form shading, loading back, determinism, the
mini cache.

The fast path renders tiny images with ``scalar_rgb``; the full-size mini recipes are ``slow``.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

pytest.importorskip("mitsuba")

from olatbench.datasets import load_scene
from olatbench.datasets.cameras import intrinsics_from_fov, look_at, project_points
from olatbench.datasets.records import Camera, PointLight
from olatbench.datasets.synth import backend
from olatbench.datasets.synth.generate import generate
from olatbench.datasets.synth.geometry import read_geometry
from olatbench.datasets.synth.mini import MANIFEST, ensure_mini_suite, file_hashes, scene_is_valid
from olatbench.datasets.synth.recipe import RECIPES, CameraRig, Recipe
from olatbench.datasets.synth.render import SceneRenderer, object_mesh
from olatbench.datasets.synth.rigs import make_rig

pytestmark = pytest.mark.usefixtures("mitsuba_scalar_variant")


def tiny(name: str = "diffuse_shadow", **overrides) -> Recipe:
    base = dict(resolution=(24, 24), spp=4, train=3, test=1, max_depth=2)
    base.update(overrides)
    return RECIPES[name].with_overrides(**base)


def test_variant_override_and_probe_cache(monkeypatch):
    assert backend.probe_variant() == "scalar_rgb"
    monkeypatch.setenv(backend.VARIANT_ENV, "llvm_ad_rgb")
    assert backend.probe_variant() == "scalar_rgb"  # cached for the process
    backend.probe_variant.cache_clear()
    assert backend.probe_variant() == "llvm_ad_rgb"


def test_opencv_to_mitsuba_axes_flip_x_and_y():
    c2w = look_at([1.0, -3.0, 2.0], [0.0, 0.0, 0.5])
    to_world = backend.mitsuba_camera_to_world(c2w)
    assert np.allclose(to_world[:3, 2], c2w[:3, 2])  # both look down +z
    assert np.allclose(to_world[:3, 0], -c2w[:3, 0])  # Mitsuba x = left
    assert np.allclose(to_world[:3, 1], -c2w[:3, 1])  # Mitsuba y = up


@pytest.mark.parametrize("fmt", ["nrhints", "gs3", "sssgs"])
def test_generated_scene_loads_back_with_the_rendered_cameras_and_lights(tmp_path, fmt):
    recipe = tiny("diffuse_shadow", shape="blob", resolution=(32, 32), novel_views=True)
    generate(recipe, tmp_path / "scene", fmt, progress=False)
    scene = load_scene(tmp_path / "scene")
    assert scene.format == fmt
    mesh = object_mesh(recipe)
    rig = make_rig(recipe, mesh.bounding_sphere()[0])
    recorded = json.loads((tmp_path / "scene" / "synth.json").read_text())
    assert np.allclose(recorded["object_bounding_sphere"]["centre"], mesh.bounding_sphere()[0])
    for split in ("train", "test"):
        loaded = scene.split(split)
        assert len(loaded) == len(rig.frames[split])
        for frame, (camera, light) in zip(loaded, rig.frames[split], strict=True):
            assert np.allclose(frame.camera.c2w, camera.c2w, atol=1e-6)
            assert np.allclose(frame.camera.K, camera.K, atol=1e-6)
            assert (frame.camera.width, frame.camera.height) == (32, 32)
            assert np.allclose(frame.light.position, light.position, atol=1e-6)
            image = frame.load(colourspace="linear", background=None)
            assert image.alpha is not None and image.alpha.max() == 1.0
            geometry = read_geometry(
                tmp_path / "scene" / "geometry" / split / f"{frame.frame_id}.exr"
            )
            check_reprojection(frame.camera, geometry, mesh, recipe.ground_radius)
            mirrored = Camera(
                K=frame.camera.K,
                c2w=frame.camera.c2w @ np.diag([-1.0, 1.0, 1.0, 1.0]),
                width=32,
                height=32,
            )
            # the check can fail: a mirrored camera does not fit the render
            with pytest.raises(AssertionError):
                check_reprojection(mirrored, geometry, mesh, recipe.ground_radius)
            # the stored alpha is the rendered foreground coverage
            assert np.mean(np.abs(image.alpha - geometry["A"])) < 0.08


def check_reprojection(camera: Camera, geometry: dict, mesh, ground_radius: float) -> None:
    """Known 3D points land where the render saw them, at the depth the render measured."""
    vertices = np.unique(mesh.vertices, axis=0)
    _, first = np.unique(mesh.vertices, axis=0, return_index=True)
    towards = camera.position - vertices
    facing = (
        np.einsum("ij,ij->i", mesh.normals[first], towards) / np.linalg.norm(towards, axis=1) > 0.3
    )
    # the bounding-sphere centre lies inside the blob: it projects into the object mask
    ((u, v),) = project_points(mesh.bounding_sphere()[0][None], camera.K, camera.c2w)[0]
    assert geometry["object"][int(v), int(u)] > 0.5
    rng = np.random.default_rng(0)
    angle, radius = (
        rng.uniform(0, 2 * np.pi, 400),
        ground_radius * np.sqrt(rng.uniform(0.3, 0.8, 400)),
    )
    ground = np.stack([radius * np.cos(angle), radius * np.sin(angle), np.zeros(400)], axis=1)
    checked = 0
    for points, mask_name in ((vertices[facing], "object"), (ground, "A")):
        uv, depth = project_points(points, camera.K, camera.c2w)
        inside = np.all((uv >= 0) & (uv < [camera.width, camera.height]), axis=1)
        px = np.floor(uv[inside]).astype(int)
        z_map = geometry["Z"][px[:, 1], px[:, 0]]
        solid = geometry["A"][px[:, 1], px[:, 0]] == 1.0
        solid &= geometry["object"][px[:, 1], px[:, 0]] == (1.0 if mask_name == "object" else 0.0)
        error = z_map[solid] - depth[inside][solid]
        # nothing visible lies behind a projected point (up to the depth spread inside one pixel)
        # ...
        assert np.percentile(error, 98) < 0.2, np.percentile(error, 98)
        # ... and most projected points are the visible surface itself (the blob hides few of its
        # front vertices)
        assert np.mean(np.abs(error) < 0.1) > 0.8, np.mean(np.abs(error) < 0.1)
        checked += int(solid.sum())
    assert checked > 50


def ground_hits(camera: Camera, px: np.ndarray, sub: int) -> tuple[np.ndarray, np.ndarray]:
    """Intersections (P, sub², 3) with z = 0 of rays through a sub × sub grid in each pixel (P, 2),
    and their rays."""
    offsets = (np.arange(sub) + 0.5) / sub
    ox, oy = np.meshgrid(offsets, offsets)
    uv = px[:, None, :] + np.stack([ox.ravel(), oy.ravel()], axis=1)[None]
    pixels = np.concatenate([uv, np.ones((*uv.shape[:2], 1))], axis=2)
    directions = pixels @ np.linalg.inv(camera.K).T @ camera.c2w[:3, :3].T
    origin = camera.position
    t = -origin[2] / directions[..., 2]
    return origin + t[..., None] * directions, directions


def segment_distance(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Distance from point ``c`` to the segments a -> b (broadcast)."""
    ab = b - a
    t = np.clip(
        np.einsum("...i,...i->...", c - a, ab) / np.einsum("...i,...i->...", ab, ab), 0.0, 1.0
    )
    return np.linalg.norm(a + t[..., None] * ab - c, axis=-1)


def test_ground_pixels_match_closed_form_lambert_with_inverse_square_and_shadow():
    """Direct light only: a lit ground pixel is albedo/π · I · cosθ / d² averaged over the pixel, in
    linear light; a pixel in the sphere's cast shadow is 0."""
    albedo, intensity = 0.5, 80.0
    recipe = Recipe(
        name="lambert",
        shape="sphere",
        ground_albedo=(albedo,) * 3,
        ground_radius=3.0,
        spp=64,
        max_depth=2,
        resolution=(40, 40),
        cameras=CameraRig(fill=0.45),
    ).validate()
    renderer = SceneRenderer(recipe)
    width, height = recipe.resolution
    camera = Camera(
        K=intrinsics_from_fov(np.radians(70), width, height),
        c2w=look_at([0.0, -3.5, 3.0], [-0.3, 0.0, 0.3]),
        width=width,
        height=height,
        near=0.1,
    )
    light = PointLight(
        position=np.array([2.0, 1.0, 3.0]), intensity=np.full(3, intensity), intensity_known=True
    )
    image = renderer.render(camera, light, seed=7)
    centre = renderer.mesh.bounding_sphere()[0]
    ys, xs = np.mgrid[0:height, 0:width]
    px = np.stack([xs.ravel(), ys.ravel()], axis=1).astype(float)
    points, directions = ground_hits(camera, px, sub=8)
    # keep pixels whose whole footprint is on the disc and whose rays pass well clear of the sphere
    ray_gap = np.linalg.norm(
        np.cross(centre - camera.position, directions), axis=-1
    ) / np.linalg.norm(directions, axis=-1)
    on_ground = (
        np.all(directions[..., 2] < 0, axis=1)
        & np.all(np.linalg.norm(points[..., :2], axis=-1) < 2.9, 1)
        & np.all(ray_gap > 1.05, axis=1)
    )
    light_gap = segment_distance(points, light.position, centre)
    lit = on_ground & np.all(light_gap > 1.05, axis=1)
    shadowed = on_ground & np.all(light_gap < 0.9, axis=1)
    assert lit.sum() > 200 and shadowed.sum() > 10
    to_light = light.position - points
    d2 = np.einsum("...i,...i->...", to_light, to_light)
    cosine = to_light[..., 2] / np.sqrt(d2)
    expected = (albedo / np.pi * intensity * cosine / d2).mean(axis=1)
    rendered = image[..., :3].reshape(-1, 3)
    assert np.all(image[..., 3].reshape(-1)[lit] == 1.0)
    relative = np.abs(rendered[lit] - expected[lit, None]) / expected[lit, None]
    assert relative.max() < 0.02, relative.max()
    assert np.abs(rendered[shadowed]).max() < 1e-6


def test_same_seed_same_files_other_seed_other_pixels(tmp_path):
    recipe = tiny("aniso_metal", train=2, test=1)
    generate(recipe, tmp_path / "a", progress=False)
    generate(recipe, tmp_path / "b", progress=False)
    generate(recipe.with_overrides(seed=1), tmp_path / "c", progress=False)
    a, b, c = (file_hashes(tmp_path / name) for name in "abc")
    assert a == b
    assert a["train/r_0000.png"] != c["train/r_0000.png"]


def test_mini_cache_reuses_verifies_and_rerenders(tmp_path, monkeypatch):
    import olatbench.datasets.synth.mini as mini

    recipes = {"one": tiny("diffuse_shadow", train=2, test=1, resolution=(16, 16))}
    root = ensure_mini_suite(tmp_path / "mini", progress=False, recipes=recipes)
    scene = root / "one"
    assert scene_is_valid(scene, recipes["one"]) == (True, "ok")
    assert load_scene(scene).split("test")
    assert not [p for p in root.iterdir() if p.name.endswith((".partial", ".stale"))]
    calls = []
    real_generate = mini.generate
    monkeypatch.setattr(mini, "generate", lambda *a, **k: calls.append(a) or real_generate(*a, **k))
    ensure_mini_suite(root, progress=False, recipes=recipes)
    assert calls == []  # reused
    (scene / "train" / "r_0000.png").write_bytes(b"corrupt")
    assert not scene_is_valid(scene, recipes["one"])[0]
    ensure_mini_suite(root, progress=False, recipes=recipes)
    assert len(calls) == 1 and scene_is_valid(scene, recipes["one"])[0]
    changed = {"one": dataclasses.replace(recipes["one"], seed=5)}
    assert not scene_is_valid(scene, changed["one"])[0]
    ensure_mini_suite(root, progress=False, recipes=changed)
    assert len(calls) == 2 and (scene / MANIFEST).is_file()
    two = {**changed, "two": tiny("diffuse_shadow", train=2, test=1, resolution=(16, 16))}
    ensure_mini_suite(root, progress=False, recipes=two, scenes=["one"])  # only what a run asks for
    assert len(calls) == 2 and not (root / "two").exists()
    with pytest.raises(KeyError, match="no scene nope"):
        ensure_mini_suite(root, progress=False, recipes=two, scenes=["nope"])


def test_mini_default_root_follows_xdg_cache_home(tmp_path, monkeypatch):
    from olatbench.datasets.synth.mini import default_root

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert default_root() == tmp_path / "olatbench" / "mini"


def test_cli_renders_a_tiny_scene_and_refuses_to_overwrite(tmp_path):
    from click.testing import CliRunner

    from olatbench.cli.synth import synth

    args = [
        "--recipe",
        "glossy_plastic",
        "--res",
        "16x12",
        "--spp",
        "2",
        "--train",
        "2",
        "--test",
        "1",
        "--out",
        str(tmp_path / "s"),
    ]
    result = CliRunner().invoke(synth, args)
    assert result.exit_code == 0, result.output
    scene = load_scene(tmp_path / "s")
    assert (scene.split("train")[0].camera.width, scene.split("train")[0].camera.height) == (16, 12)
    again = CliRunner().invoke(synth, args)
    assert again.exit_code == 2 and "already exists" in again.output
    bad = CliRunner().invoke(
        synth, ["--recipe", "glossy_plastic", "--res", "big", "--out", str(tmp_path / "t")]
    )
    assert bad.exit_code == 2 and "--res" in bad.output


@pytest.mark.slow
@pytest.mark.parametrize("name", ["diffuse_shadow", "aniso_metal", "translucent"])
def test_mini_recipes_fill_the_frame_and_are_well_exposed(name):
    """Full-size mini frames: the object covers a good part of the image and is neither black nor
    clipped."""
    recipe = RECIPES[name]
    renderer = SceneRenderer(recipe)
    rig = make_rig(recipe, renderer.mesh.bounding_sphere()[0])
    for index in (0, 37, 71):
        camera, light = rig.frames["train"][index]
        image = renderer.render(camera, light, seed=index)
        geometry = renderer.geometry(camera)
        object_fraction = float(np.mean(geometry["object"] > 0.5))
        assert 0.12 < object_fraction < 0.6, object_fraction
        foreground = image[..., 3] > 0.99
        assert np.mean(image[..., :3][foreground] >= 1.0) < 0.05  # few clipped values
        assert np.percentile(image[..., :3][foreground], 90) > 0.05  # lit, not black


def test_user_mesh_file_is_read_normalised_and_rendered(tmp_path):
    from olatbench.datasets.synth.meshes import is_watertight, torus

    mesh = torus(16)
    # any scale and offset
    lines = [f"v {x} {y} {z}" for x, y, z in mesh.vertices * 3.0 + [5.0, 0.0, 2.0]]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in mesh.faces]
    (tmp_path / "ring.obj").write_text("\n".join(lines) + "\n")
    (tmp_path / "ring.json").write_text(
        json.dumps({"shape": "ring.obj", "resolution": [16, 16], "spp": 2, "train": 1, "test": 0})
    )
    from olatbench.datasets.synth.recipe import get_recipe

    recipe = get_recipe(tmp_path / "ring.json")
    loaded = object_mesh(recipe)
    centre, radius = loaded.bounding_sphere()
    assert radius == pytest.approx(1.0) and loaded.vertices[:, 2].min() == pytest.approx(
        1e-3, abs=1e-6
    )
    assert is_watertight(loaded) and len(loaded.faces) == len(mesh.faces)
    renderer = SceneRenderer(recipe, loaded)
    camera, light = make_rig(recipe, centre).frames["train"][0]
    assert renderer.geometry(camera)["object"].mean() > 0.05
    assert renderer.render(camera, light, seed=0)[..., 3].max() == 1.0
