"""Rendering a trained method under a lighting (#57, `olatbench.bench.relight`): light adds up in
linear light, a far point light is the directional light, and an environment relight of a Lambertian
sphere converges to its closed form as the samples grow."""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass

import numpy as np
import pytest
import torch
from ssdgs_scenes import sphere_views

from olatbench.bench.relight import LightingReference, Relighter, RelightError, probes
from olatbench.datasets import colour
from olatbench.datasets.images import write_image
from olatbench.datasets.lighting import DirectionalLight, SampledLights, read_lighting
from olatbench.datasets.lighting.envmap import pixel_directions
from olatbench.datasets.records import Camera, PointLight
from olatbench.datasets.synth.analytic import ALBEDO, render_sphere, sphere_hits
from olatbench.methods.base import Method, Views


class AnalyticSphere(Method):
    """The closed-form Lambertian sphere (`olatbench.datasets.synth.analytic`) as a method: linear
    radiance, clipped to [0, 1] as the methods clip theirs, on ``background``, with its coverage."""

    name = "analytic-sphere"
    capabilities = frozenset({"relight"})

    @dataclass
    class Config:
        iterations: int = 1
        background: float = 0.0

    config_class = Config

    def setup(self, train, device, seed) -> None:
        pass

    def train_step(self, step):  # pragma: no cover
        raise AssertionError("not trained")

    def render(self, camera, light):
        hit = sphere_hits(camera)[1]
        return {
            "rgb": torch.from_numpy(render_sphere(camera, light, self.config.background)),
            "alpha": torch.from_numpy(hit.astype(np.float32))[..., None],
        }

    def state_dict(self):
        return {}

    def load_state_dict(self, state) -> None:
        pass


def analytic(background: float = 0.0, size: int = 24) -> tuple[Relighter, Views]:
    views = dataclasses.replace(
        sphere_views(6, size=size),
        colourspace="linear",
        background=np.full(3, background, dtype=np.float32),
    )
    method = AnalyticSphere(AnalyticSphere.Config(background=background))
    relighter = Relighter.for_views(method, views)
    # an exact renderer: directional lights as point lights far away
    relighter.distant_factor = 1000.0
    return relighter, views


def gaussian(name: str, background: float = 0.0) -> tuple[Relighter, Views]:
    """An untrained SSD-GS / GS³ / 3DGS on the sphere's views (sRGB, as the mini suite), every term
    switched on."""
    from olatbench.methods.registry import get_spec

    module, attribute = get_spec(name).implementation.split(":")
    cls = getattr(__import__(module, fromlist=[attribute]), attribute)
    views = sphere_views(6, size=24, background=background)
    extra = {"shadow_resolution": 32} if name == "ssdgs" else {}
    method = cls(cls.resolve_config("mini", num_init_gaussians=300, init_opacity=0.6, **extra))
    method.setup(views, "cpu", 0)
    method.step = 10**6  # past every schedule: shadows, specular and subsurface terms all on
    return Relighter.for_views(method, views), views


def reference_light(relighter: Relighter, direction, scale: float = 1.0) -> PointLight:
    """A point light at the training lights' distance whose irradiance at the centre is ``scale`` ×
    theirs, so that it is its own probe (rendered as it is, weighted by ``scale``)."""
    ref = relighter.reference
    unit = np.asarray(direction, dtype=np.float64) / np.linalg.norm(direction)
    return PointLight(
        ref.centre + ref.distance * unit, scale * ref.irradiance * ref.distance**2, True
    )


def decoded(relighter: Relighter, camera: Camera, light: PointLight) -> np.ndarray:
    """The method's own render under ``light``, decoded from the job's colour space to linear
    light."""
    rgb = relighter.method.render(camera, light)["rgb"].numpy()
    return colour.convert_colourspace(rgb, relighter.colourspace, "linear")


@pytest.mark.parametrize("name", ["ssdgs", "gs3", "3dgs"])
def test_a_two_light_render_is_the_sum_of_the_single_light_renders(name):
    relighter, views = gaussian(name)
    camera = views.cameras[0]
    # lights beside the camera: the lit side
    towards = camera.position / np.linalg.norm(camera.position)
    a = reference_light(relighter, towards + np.array([0.4, 0.0, 0.2]))
    # 3 × the training irradiance
    b = reference_light(relighter, towards + np.array([-0.3, 0.4, 0.0]), scale=3.0)
    together = relighter.linear(camera, SampledLights((a, b)))
    one = decoded(relighter, camera, a)
    other = decoded(relighter, camera, dataclasses.replace(b, intensity=a.intensity))
    assert one.max() > 1e-3 and other.max() > 1e-3  # light lands on the model
    # each light's image decoded to linear light, the second three times brighter there: not in sRGB
    np.testing.assert_allclose(together, one + 3.0 * other, rtol=1e-5, atol=1e-6)
    alone = relighter.linear(camera, SampledLights((a,)))
    np.testing.assert_allclose(alone, one, rtol=1e-5, atol=1e-6)
    if name != "3dgs":  # a relightable method: the two lights give different images
        assert np.abs(one - other).max() > 1e-3


@pytest.mark.parametrize("name", ["ssdgs", "gs3"])
def test_the_background_counts_once_however_many_lights(name):
    relighter, views = gaussian(name, background=1.0)
    c2w = views.cameras[0].c2w.copy()
    # four times as far: the model's initial ball leaves the image's corners empty
    c2w[:3, 3] *= 4.0
    camera = dataclasses.replace(views.cameras[0], c2w=c2w)
    lights = SampledLights(
        tuple(reference_light(relighter, d) for d in ([1, 0, 1], [0, 1, 1], [-1, 0, 1]))
    )
    image = relighter.linear(camera, lights)
    empty = relighter.method.render(camera, lights.points[0])["alpha"].numpy()[..., 0] < 1e-4
    assert empty.any() and (~empty).any()
    np.testing.assert_allclose(image[empty], 1.0, atol=1e-5)  # white once, not three times


def test_background_removal_is_exact_on_the_analytic_sphere():
    relighter, views = analytic(background=1.0)
    black, _ = analytic(background=0.0)
    camera = views.cameras[1]
    lights = SampledLights(tuple(reference_light(relighter, d) for d in ([1, 0, 1], [0, 1, 1])))
    hit = sphere_hits(camera)[1]
    with_background, without = relighter.linear(camera, lights), black.linear(camera, lights)
    np.testing.assert_allclose(with_background[hit], without[hit], atol=1e-6)
    np.testing.assert_allclose(with_background[~hit], 1.0)


def far_light_errors(relighter: Relighter, camera: Camera, factors) -> list[float]:
    """Largest linear difference, over the directional light's brightest pixel, between point lights
    at ``factors`` × the training lights' distance (intensity E d²) and the directional light E
    along the same direction (from the camera's side: the lit side)."""
    direction = camera.position / np.linalg.norm(camera.position) + np.array([0.3, -0.2, 0.3])
    direction, irradiance = direction / np.linalg.norm(direction), np.array([1.5, 1.2, 0.9])
    distant = relighter.linear(
        camera, SampledLights(directions=(DirectionalLight(direction, irradiance),))
    )
    peak = float(distant.max())
    assert peak > 1e-3
    errors = []
    for factor in factors:
        d = factor * relighter.reference.distance
        point = PointLight(relighter.reference.centre + d * direction, irradiance * d**2, True)
        errors.append(
            float(np.abs(relighter.linear(camera, SampledLights((point,))) - distant).max()) / peak
        )
    return errors


def test_a_far_point_light_converges_to_the_directional_light_on_the_analytic_sphere():
    relighter, views = analytic()
    errors = far_light_errors(relighter, views.cameras[0], (2.0, 20.0, 200.0))
    assert errors[0] > 0.05  # near, the light's parallax and falloff across the sphere show
    assert 5.0 < errors[0] / errors[1] < 20.0 and 5.0 < errors[1] / errors[2] < 20.0  # error ∝ 1/d


@pytest.mark.parametrize("name", ["ssdgs", "gs3"])
def test_a_far_point_light_converges_to_the_directional_light_for_the_gaussian_methods(name):
    """Through each method's own shading and light-view shadow pass: no blow-up far away, and the d²
    scaling (directional lights probed far away here; by default at the training distance, where
    trained models are in their training regime: `olatbench.bench.relight`)."""
    relighter, views = gaussian(name)
    relighter.distant_factor = 1000.0
    errors = far_light_errors(relighter, views.cameras[0], (1.5, 15.0, 150.0))
    assert errors[0] > 10 * errors[2] and errors[1] > errors[2]
    assert errors[2] < 0.01


def gradient_map(height: int, a: float, b: float) -> np.ndarray:
    """The equirectangular map of L(ω) = a + b·(ω·up), (H, 2H, 3)."""
    theta, _ = pixel_directions(height, 2 * height)
    return np.repeat((a + b * np.cos(theta))[..., None], 2 * height, axis=1).repeat(3, axis=2)


def test_an_environment_relight_of_the_lambertian_sphere_converges_to_the_closed_form(tmp_path):
    """L(ω) = a + b ω_z gives a Lambertian point of normal n the irradiance ∫ L max(n·ω, 0) dω = aπ
    + (2π/3) b n_z: the relight through an .exr map and the relighter approaches ALBEDO × that, its
    error falling with the sample count at least as K^-1/2 (stratified importance sampling)."""
    a, b = 0.3, 0.2
    write_image(
        tmp_path / "gradient.exr", gradient_map(256, a, b).astype(np.float32), bit_depth="float"
    )
    relighter, views = analytic(size=20)
    camera = views.cameras[2]
    normals, hit = sphere_hits(camera)
    exact = ALBEDO * (a * np.pi + 2.0 * np.pi / 3.0 * b * normals[..., 2:3])[hit]
    counts, seeds = (16, 64, 256, 1024), range(3)
    errors = []
    for count in counts:
        rms = []
        for seed in seeds:
            (tmp_path / "env.json").write_text(
                json.dumps(
                    {
                        "seed": seed,
                        "lights": [
                            {
                                "type": "envmap",
                                "map": "gradient.exr",
                                "up": [0, 0, 1],
                                "samples": count,
                            }
                        ],
                    }
                )
            )
            lights = read_lighting(tmp_path / "env.json").sample()
            assert len(lights.directions) == count
            rms.append(np.sqrt(np.mean((relighter.linear(camera, lights)[hit] - exact) ** 2)))
        errors.append(float(np.mean(rms)))
    slope = np.polyfit(np.log(counts), np.log(errors), 1)[0]
    assert slope < -0.5, (errors, slope)
    assert errors[-1] < 0.02 * float(np.mean(exact)), errors


def test_probes_render_at_the_training_irradiance():
    cameras, lights = sphere_views(6, size=16).cameras, sphere_views(6, size=16).lights
    reference = LightingReference.of(cameras, lights)
    # the analytic rig: I = 16 at distance 5
    np.testing.assert_allclose(reference.irradiance, 16.0 / 25.0)
    np.testing.assert_allclose(reference.centre, 0.0, atol=1e-9)
    near = PointLight(np.array([0.0, 0.0, 2.0]), np.array([8.0, 4.0, 2.0]), True)
    far = DirectionalLight(np.array([1.0, 0.0, 0.0]), np.array([0.2, 0.2, 0.2]))
    # at the training distance
    point_probe, distant_probe = probes(SampledLights((near,), (far,)), reference)
    np.testing.assert_allclose(point_probe.light.intensity / 4.0, reference.irradiance)  # at d = 2
    np.testing.assert_allclose(point_probe.weight, np.array([8.0, 4.0, 2.0]) / 4.0 / 0.64)
    np.testing.assert_allclose(distant_probe.light.position, [5.0, 0, 0], atol=1e-9)
    # the training irradiance there
    np.testing.assert_allclose(distant_probe.light.intensity, 0.64 * 25.0)
    np.testing.assert_allclose(distant_probe.weight, 0.2 / 0.64)
    far_probe = probes(SampledLights(directions=(far,)), reference, distant_factor=1000.0)[0]
    np.testing.assert_allclose(far_probe.light.position, [5000.0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(far_probe.light.intensity, 0.64 * 5000.0**2)
    np.testing.assert_allclose(far_probe.weight, 0.2 / 0.64)
    with pytest.raises(RelightError, match="at the scene centre"):
        probes(SampledLights((PointLight(np.zeros(3), np.ones(3), True),)), reference)
