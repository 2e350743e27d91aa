"""Lightings (#57): the torch-free light description, its JSON files, area lights and
environment-map sampling."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from olatbench.datasets.errors import DatasetError
from olatbench.datasets.images import write_image
from olatbench.datasets.lighting import (
    BUILT_IN_MAPS,
    DirectionalLight,
    EnvironmentMap,
    Lighting,
    RectLight,
    SphereLight,
    environment_lighting,
    lighting_from_dict,
    lighting_to_dict,
    read_lighting,
    sample_map,
    write_lighting,
)
from olatbench.datasets.lighting.envmap import map_axes, pixel_directions, pixel_solid_angles
from olatbench.datasets.records import PointLight

ALL_KINDS = {
    "samples": 8,
    "seed": 3,
    "lights": [
        {"type": "point", "position": [1, 2, 3], "intensity": [4, 5, 6]},
        {"type": "directional", "direction": [0, 0, 2], "irradiance": 1.5},
        {
            "type": "sphere",
            "centre": [0, 0, 4],
            "radius": 0.5,
            "intensity": [8, 8, 8],
            "samples": 5,
        },
        {
            "type": "rect",
            "centre": [0, 3, 0],
            "u": [1, 0, 0],
            "v": [0, 0, 2],
            "intensity": [2, 2, 2],
        },
        {
            "type": "envmap",
            "map": "furnace",
            "rotation": 30,
            "exposure": -1,
            "up": [0, 1, 0],
            "samples": 7,
        },
    ],
}


def test_import_of_the_lighting_layer_needs_no_torch():
    code = (
        "import sys, olatbench.datasets.lighting, olatbench.datasets.lighting.files; "
        "sys.exit('torch' in sys.modules)"
    )
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0


def test_json_round_trip_and_every_kind_of_light(tmp_path):
    lighting = lighting_from_dict(ALL_KINDS)
    point, directional, sphere, rect, envmap = lighting.sources
    assert isinstance(point, PointLight) and point.intensity_known
    np.testing.assert_allclose(directional.direction, [0, 0, 1])  # normalised
    np.testing.assert_allclose(directional.irradiance, [1.5] * 3)  # a grey number
    assert isinstance(sphere, SphereLight) and sphere.samples == 5 and isinstance(rect, RectLight)
    assert isinstance(envmap, EnvironmentMap) and envmap.rotation == 30 and envmap.exposure == -1
    path = write_lighting(tmp_path / "all.json", lighting)
    again = read_lighting(path)
    assert lighting_to_dict(again) == lighting_to_dict(lighting)
    sampled = again.sample()
    # 1 point + 5 on the sphere + 8 (the file's default) on the rectangle; 1 directional + 7 from
    # the map
    assert len(sampled.points) == 14 and len(sampled.directions) == 8
    assert len(again.sample(samples=3).points) == 1 + 3 + 3  # an override of every count
    first, second = again.sample(), again.sample()  # seeded: the same lights each time
    np.testing.assert_array_equal(first.directions[-1].direction, second.directions[-1].direction)


@pytest.mark.parametrize(
    ("edit", "key", "message"),
    [
        (lambda d: d["lights"][0].pop("position"), "lights[0].position", "missing"),
        (
            lambda d: d["lights"][0].update(intensity=[1, -2, 3]),
            "lights[0].intensity",
            "non-negative",
        ),
        (
            lambda d: d["lights"][1].update(direction=[0, 0, 0]),
            "lights[1].direction",
            "zero vector",
        ),
        (lambda d: d["lights"][2].update(radius=0), "lights[2].radius", "must be > 0"),
        (lambda d: d["lights"][2].update(samples=0), "lights[2].samples", "whole number"),
        (lambda d: d["lights"][3].update(v=[2, 0, 0]), "lights[3].v", "span a rectangle"),
        (lambda d: d["lights"][4].update(type="spot"), "lights[4].type", "expected one of point"),
        (lambda d: d["lights"][4].update(colour=1), "lights[4].colour", "unknown field"),
        (lambda d: d.update(lights=[]), "lights", "non-empty list"),
        (lambda d: d.update(seed=-1), "seed", "whole number"),
    ],
)
def test_a_bad_field_is_one_error_naming_the_file_and_the_field(tmp_path, edit, key, message):
    data = json.loads(json.dumps(ALL_KINDS))
    edit(data)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(DatasetError) as caught:
        read_lighting(path)
    assert (
        str(path) in str(caught.value)
        and f"key '{key}'" in str(caught.value)
        and message in str(caught.value)
    )
    assert "\n" not in str(caught.value)


def test_unreadable_files_and_maps_name_the_file(tmp_path):
    broken = tmp_path / "broken.json"
    broken.write_text('{"lights": [')
    with pytest.raises(DatasetError, match=r"broken\.json: malformed JSON"):
        read_lighting(broken)
    with pytest.raises(DatasetError, match=r"missing\.json: cannot read"):
        read_lighting(tmp_path / "missing.json")
    (tmp_path / "map.json").write_text(
        json.dumps({"lights": [{"type": "envmap", "map": "nowhere.exr"}]})
    )
    with pytest.raises(DatasetError, match=r"nowhere\.exr"):
        read_lighting(tmp_path / "map.json").sample()
    with pytest.raises(DatasetError, match="studio, sky, furnace"):
        environment_lighting("forest").sample()


def test_area_lights_keep_their_total_intensity_and_their_shape():
    sphere = Lighting(
        (SphereLight(np.array([1.0, 2.0, 3.0]), 0.5, np.array([6.0, 3.0, 1.0]), 64),)
    ).sample()
    positions = np.array([light.position for light in sphere.points])
    np.testing.assert_allclose(np.linalg.norm(positions - [1, 2, 3], axis=1), 0.5)
    np.testing.assert_allclose(
        np.sum([light.intensity for light in sphere.points], axis=0), [6, 3, 1]
    )
    # evenly spread: no side favoured
    np.testing.assert_allclose(positions.mean(0), [1, 2, 3], atol=0.02)
    rect = Lighting(
        (RectLight(np.zeros(3), np.array([2.0, 0, 0]), np.array([0, 0, 1.0]), np.ones(3), 50),)
    ).sample()
    corners = np.array([light.position for light in rect.points])
    assert np.all(np.abs(corners[:, 0]) <= 1.0) and np.all(np.abs(corners[:, 2]) <= 0.5)
    np.testing.assert_allclose(corners[:, 1], 0.0)
    # stratified: every tenth of the rectangle's width holds five of the fifty points
    assert np.all(np.bincount(((corners[:, 0] + 1.0) / 2.0 * 10).astype(int), minlength=10) == 5)


def test_furnace_samples_integrate_exactly_and_cover_the_sphere():
    directions, irradiance = sample_map(
        BUILT_IN_MAPS["furnace"](), 200, np.random.default_rng(1), np.array([0.0, 0.0, 1.0])
    )
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0)
    np.testing.assert_allclose(irradiance, 4.0 * np.pi / 200)  # L = 1 over 4π sr, shared equally
    # stratified in cos θ: upper and lower halves balanced
    assert abs(directions[:, 2].mean()) < 0.02


def test_sampling_follows_the_radiance_rotation_exposure_and_up():
    height = 64
    radiance = np.full((height, 2 * height, 3), 1e-3)
    radiance[10:14, 0:4] = 100.0  # a bright patch near azimuth 0, 62° from up
    theta, phi = pixel_directions(height, 2 * height)
    patch = np.array(
        [
            np.sin(theta[12, 0]) * np.cos(phi[0, 2]),
            np.sin(theta[12, 0]) * np.sin(phi[0, 2]),
            np.cos(theta[12, 0]),
        ]
    )
    rng = np.random.default_rng(0)
    up = np.array([0.0, 1.0, 0.0])
    directions, irradiance = sample_map(radiance, 256, rng, up, rotation_deg=90.0, exposure=1.0)
    turned = np.array([-patch[1], patch[0], patch[2]])  # +90° about the map's up
    on_patch = directions @ (turned @ map_axes(up)) > np.cos(np.radians(9.0))
    # importance: almost all samples on the patch, where rotation and up put it
    assert on_patch.mean() > 0.95
    # not where it was
    assert not np.any(directions @ (patch @ map_axes(up)) > np.cos(np.radians(9.0)))
    # the estimate of the total power is the map's, doubled by one stop of exposure
    total = (radiance * pixel_solid_angles(height, 2 * height)[..., None]).sum((0, 1)) * 2.0
    np.testing.assert_allclose(irradiance.sum(0), total, rtol=1e-9)  # constant within pixels: exact


def test_built_in_maps_and_an_exr_file_load(tmp_path):
    for name in BUILT_IN_MAPS:
        radiance = environment_lighting(name).sources[0].radiance()
        assert (
            radiance.ndim == 3
            and radiance.shape[1] == 2 * radiance.shape[0]
            and radiance.min() >= 0.0
        )
    studio = BUILT_IN_MAPS["studio"]()
    sky = BUILT_IN_MAPS["sky"]()
    # soft boxes; the sun
    assert studio.max() > 100 * studio.min() and sky.max() > 1000 * np.median(sky)
    pixels = np.random.default_rng(0).uniform(0, 4, (8, 16, 3)).astype(np.float32)
    write_image(tmp_path / "room.exr", pixels, bit_depth="float")
    (tmp_path / "room.json").write_text(
        json.dumps({"lights": [{"type": "envmap", "map": "room.exr"}]})
    )
    np.testing.assert_array_equal(
        read_lighting(tmp_path / "room.json").sources[0].radiance(), pixels
    )
    # Radiance RGBE: 8-bit mantissas under a shared exponent (≤ 4 / 128)
    write_image(tmp_path / "room.hdr", pixels)
    np.testing.assert_allclose(
        environment_lighting(str(tmp_path / "room.hdr")).sources[0].radiance(),
        pixels,
        atol=4.0 / 128,
    )
    write_image(tmp_path / "tall.exr", pixels.transpose(1, 0, 2), bit_depth="float")
    with pytest.raises(DatasetError, match="twice as wide as high"):
        environment_lighting(str(tmp_path / "tall.exr")).sample()


def test_directional_lights_need_no_sampling():
    light = DirectionalLight(np.array([0.0, 0.0, 1.0]), np.ones(3))
    sampled = Lighting((light,)).sample()
    assert sampled.directions == (light,) and sampled.points == ()
