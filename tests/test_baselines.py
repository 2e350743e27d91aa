"""In-process baselines: SH closed forms, the GS³ screen-space composite by hand, schedules,
training, presets."""

from __future__ import annotations

import dataclasses
import io
import math

import numpy as np
import pytest
import torch
from ssdgs_scenes import sphere_views

from olatbench.datasets.cameras import intrinsics_from_fov, look_at
from olatbench.gaussians.projection import project
from olatbench.methods import registry
from olatbench.methods.baselines import sh
from olatbench.methods.baselines.gs3 import GS3
from olatbench.methods.baselines.gs3dgs import GaussianSplatting3D
from olatbench.methods.baselines.triple_splat import triple_splat
from olatbench.methods.registry import get_method, register

TINY = {
    "num_init_gaussians": 300,
    "init_radius": 1.3,
    "max_gaussians": 2_000,
    "densify_from": 100_000,
    "densify_until": 100_000,
    "opacity_reset_interval": 100_000,
}


@pytest.fixture(scope="module")
def views():
    return sphere_views(4, size=24, seed=3)


def mean_l1(method, views) -> float:
    errors = [
        float((method.render(c, lt)["rgb"] - torch.from_numpy(img)).abs().mean())
        for c, lt, img in zip(views.cameras, views.lights, views.images, strict=True)
    ]
    return float(np.mean(errors))


# ----------------------------------------------------------------------------------------------- SH
def test_sh_closed_forms_at_known_directions() -> None:
    pole = sh.sh_basis(3, torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64))
    zonal = {0: 0, 1: 2, 2: 6, 3: 12}  # index of m = 0 in each degree
    # Y_l0 at the pole = sqrt((2l + 1) / 4π), every other term 0
    for degree, index in zonal.items():
        assert pole[index].item() == pytest.approx(
            math.sqrt((2 * degree + 1) / (4 * math.pi)), rel=1e-12
        )
    assert pole[[i for i in range(16) if i not in zonal.values()]].abs().max().item() < 1e-15
    # unit: .2304 + .36 + .4096
    x, y, z = (torch.tensor(v, dtype=torch.float64) for v in (0.48, -0.6, 0.64))
    basis = sh.sh_basis(3, torch.stack([x, y, z]))
    expected = {
        1: -math.sqrt(3 / (4 * math.pi)) * y,
        3: -math.sqrt(3 / (4 * math.pi)) * x,
        4: 0.5 * math.sqrt(15 / math.pi) * x * y,
        6: 0.25 * math.sqrt(5 / math.pi) * (3 * z * z - 1),
        8: 0.25 * math.sqrt(15 / math.pi) * (x * x - y * y),
        9: -0.25 * math.sqrt(35 / (2 * math.pi)) * y * (3 * x * x - y * y),
        10: 0.5 * math.sqrt(105 / math.pi) * x * y * z,
        12: 0.25 * math.sqrt(7 / math.pi) * z * (5 * z * z - 3),
        15: -0.25 * math.sqrt(35 / (2 * math.pi)) * x * (x * x - 3 * y * y),
    }
    for index, value in expected.items():
        assert basis[index].item() == pytest.approx(float(value), rel=1e-12, abs=1e-15), index


def test_sh_basis_is_orthonormal_on_the_sphere() -> None:
    nodes, weights = np.polynomial.legendre.leggauss(8)  # exact for the degree ≤ 6 products
    phi = np.arange(16) * 2 * np.pi / 16
    cos_t, ph = np.meshgrid(nodes, phi, indexing="ij")
    sin_t = np.sqrt(1 - cos_t**2)
    dirs = torch.from_numpy(
        np.stack([sin_t * np.cos(ph), sin_t * np.sin(ph), cos_t], -1).reshape(-1, 3)
    )
    w = torch.from_numpy(np.repeat(weights, 16) * 2 * np.pi / 16)
    basis = sh.sh_basis(3, dirs)
    gram = basis.T @ (basis * w[:, None])
    torch.testing.assert_close(gram, torch.eye(16, dtype=torch.float64), atol=1e-12, rtol=0)


def test_eval_sh_uses_only_the_active_degree() -> None:
    coefficients = torch.randn(5, 16, 3, dtype=torch.float64)
    dirs = torch.nn.functional.normalize(torch.randn(5, 3, dtype=torch.float64), dim=-1)
    for degree in range(4):
        k = (degree + 1) ** 2
        manual = torch.einsum("nk,nkc->nc", sh.sh_basis(3, dirs)[:, :k], coefficients[:, :k])
        torch.testing.assert_close(sh.eval_sh(degree, coefficients, dirs), manual)
    assert (
        sh.eval_sh(0, sh.rgb_to_sh_dc(torch.full((1, 1, 3), 0.8)), dirs[:1])
        .add(0.5)
        .allclose(torch.full((1, 3), 0.8, dtype=torch.float32).double())
    )


# ------------------------------------------------------------------------------ GS³ screen-space
# composite
def _two_gaussians():
    K = torch.tensor(intrinsics_from_fov(math.radians(40.0), 16, 16), dtype=torch.float32)
    w2c = torch.tensor(
        np.linalg.inv(look_at(np.array([0.0, -4.0, 0.0]), np.zeros(3))), dtype=torch.float32
    )
    means = torch.tensor([[0.05, 0.5, 0.0], [-0.05, -0.5, 0.05]])  # the second is nearer the camera
    quats = torch.tensor([[1.0, 0.0, 0.0, 0.0], [0.9, 0.1, 0.2, 0.0]])
    scales = torch.tensor([[0.3, 0.2, 0.25], [0.2, 0.3, 0.15]])
    return project(means, quats, scales, w2c, K, 16, 16)


@pytest.mark.parametrize("background", [0.0, 1.0])
def test_gs3_composite_matches_a_hand_computation(background: float) -> None:
    projected = _two_gaussians()
    opacities = torch.tensor([0.7, 0.6])
    shading = torch.tensor([[0.9, 0.2, 0.1], [0.1, 0.5, 0.8]])
    visibility = torch.tensor([[0.3], [0.8]])
    other = torch.tensor([[0.05, 0.0, 0.1], [0.2, 0.1, 0.0]])
    bg = torch.full((3,), background)
    splat = triple_splat(projected, opacities, shading, visibility, other, bg, backend="torch")

    px, py = 8, 8
    order = torch.argsort(projected.depths)
    T, I_px, V_px, O_px = 1.0, torch.zeros(3), torch.zeros(1), torch.zeros(3)
    for i in order.tolist():  # front to back
        d = torch.tensor([px + 0.5, py + 0.5]) - projected.means2d[i]
        a, b, c = projected.conics[i].tolist()
        power = -0.5 * (a * d[0] ** 2 + 2 * b * d[0] * d[1] + c * d[1] ** 2)
        alpha = min(0.99, float(opacities[i] * torch.exp(power)))
        assert alpha > 1 / 255  # both Gaussians cover the pixel
        I_px, V_px, O_px = (
            I_px + T * alpha * shading[i],
            V_px + T * alpha * visibility[i],
            O_px + T * alpha * other[i],
        )
        T *= 1 - alpha
    I_px, V_px = I_px + T * bg, V_px + T * (1.0 if background > 0 else 0.0)
    torch.testing.assert_close(splat.shading[py, px], I_px, atol=1e-6, rtol=1e-5)
    torch.testing.assert_close(splat.visibility[py, px], V_px, atol=1e-6, rtol=1e-5)
    torch.testing.assert_close(splat.other[py, px], O_px, atol=1e-6, rtol=1e-5)
    torch.testing.assert_close(splat.image[py, px], I_px * V_px + O_px, atol=1e-6, rtol=1e-5)
    # Screen-space shadowing differs from shadowing each Gaussian before blending (SSD-GS's order).
    per_gaussian = triple_splat(
        projected, opacities, shading * visibility, torch.ones(2, 1), other, bg, backend="torch"
    )
    assert (per_gaussian.shading[py, px] + O_px - splat.image[py, px]).abs().max() > 1e-3
    # An empty corner pixel shows the background.
    torch.testing.assert_close(splat.image[0, 0], bg)


# ------------------------------------------------------------------------------------------- 3DGS
def test_3dgs_lowers_the_loss_ignores_the_light_and_resumes(views, monkeypatch) -> None:
    # the built-in spec back afterwards
    monkeypatch.setattr(registry, "_registered", dict(registry._registered))
    register("3dgs", GaussianSplatting3D)
    assert get_method("3dgs") is GaussianSplatting3D
    method = GaussianSplatting3D(
        GaussianSplatting3D.resolve_config("mini", iterations=40, sh_increase_interval=10, **TINY)
    )
    method.setup(views, "cpu", 0)
    before = mean_l1(method, views)
    for step in range(30):
        method.train_step(step)
    assert mean_l1(method, views) < 0.8 * before
    assert method.active_sh_degree(29) == 2 and method.active_sh_degree(39) == 3
    camera = views.cameras[0]
    torch.testing.assert_close(
        method.render(camera, views.lights[0])["rgb"], method.render(camera, views.lights[1])["rgb"]
    )

    buffer = io.BytesIO()
    torch.save(method.state_dict(), buffer)
    buffer.seek(0)
    restored = GaussianSplatting3D(method.config)
    restored.setup(views, "cpu", 5)
    restored.load_state_dict(torch.load(buffer, weights_only=True))
    torch.testing.assert_close(
        restored.render(camera, views.lights[0])["rgb"],
        method.render(camera, views.lights[0])["rgb"],
    )
    a, b = method.train_step(30), restored.train_step(30)
    assert a["loss"] == pytest.approx(b["loss"], rel=1e-6)


# -------------------------------------------------------------------------------------------- GS³
def make_gs3(views, **overrides) -> GS3:
    values = {
        "iterations": 100,
        "reference_iterations": 100,
        "shadow_from": 5,
        "mlp_freeze_from": 20,
        "specular_from": 30,
        "asg_lobes_from": 40,
        "shadow_resolution": 24,
        "other_hidden": 16,
        "num_asg": 4,
        **TINY,
        **overrides,
    }
    method = GS3(GS3.resolve_config(None, **values))
    method.setup(views, "cpu", 0)
    return method


def test_gs3_gradients_follow_its_schedule(views) -> None:
    method = make_gs3(views)
    groups = {
        "shadow": list(method.shader.shadow_net.parameters()),
        "other": list(method.shader.other_net.parameters()),
        "material": [method.model.attributes["material"]],
        "specular": [method.model.attributes["specular"], method.model.attributes["asg_weights"]],
        "lobes": list(method.shader.asg.parameters()),
    }
    expected = {  # step: groups with gradients
        0: set(),
        5: {"shadow", "other", "material"},
        20: set(),
        30: {"shadow", "other", "material", "specular"},
        40: {"shadow", "other", "material", "specular", "lobes"},
    }
    for step, with_grad in expected.items():
        for p in [*method.model.parameters(), *method.shader.parameters()]:
            p.grad = None
        method.compute_gradients(step, index=0)
        for name, params in groups.items():
            got = any(p.grad is not None and bool(p.grad.abs().sum() > 0) for p in params)
            assert got == (name in with_grad), f"step {step}: {name}"
        assert method.model.attributes["diffuse"].grad.abs().sum() > 0


def test_gs3_lowers_the_loss_and_renders_its_components(views, monkeypatch) -> None:
    # the built-in spec back afterwards
    monkeypatch.setattr(registry, "_registered", dict(registry._registered))
    register("gs3", GS3)
    method = make_gs3(views)
    before = mean_l1(method, views)
    # the loss rises over the first ~10 steps from opacity 0.1, then falls (0.099 -> 0.038)
    for step in range(60):
        method.train_step(step)
    assert mean_l1(method, views) < 0.8 * before
    out = method.render(views.cameras[0], views.lights[0])
    assert set(out) == {
        "rgb",
        "diffuse",
        "specular",
        "shading",
        "shadow",
        "shadow_coarse",
        "other",
        "alpha",
    }
    torch.testing.assert_close(
        out["rgb"], (out["shading"] * out["shadow"] + out["other"]).clamp(0, 1)
    )
    torch.testing.assert_close(
        out["shading"], out["diffuse"] + out["specular"], atol=1e-5, rtol=1e-5
    )


@pytest.mark.parametrize("initial_shading", [0.5, None])
def test_gs3_starts_below_white_under_bright_recorded_lights(views, initial_shading) -> None:
    """Lights of intensity 400 at distance 5 (I/d² = 16): with the official start
    (initial_shading=None) most of the composite is above 1, where the loss's clamp passes no
    gradient; with the bound it is not."""
    bright = dataclasses.replace(
        views,
        lights=[dataclasses.replace(light, intensity=np.full(3, 400.0)) for light in views.lights],
    )
    config = GS3.resolve_config("mini", num_init_gaussians=300, initial_shading=initial_shading)
    method = GS3(config)
    method.setup(bright, "cpu", 0)
    with torch.no_grad():
        image = method.training_forward(0, config.steps(config.shadow_from))["image"]  # I·V + O
    covered = image.sum(-1) > 0.05
    above_white = float((image[covered] > 1.0).float().mean())
    assert above_white > 0.5 if initial_shading is None else above_white < 0.02
    # the ball's centre is near the sphere's
    assert method.irradiance == pytest.approx(16.0, rel=0.35)


def test_gs3_keeps_the_official_start_when_the_intensity_is_ignored(views) -> None:
    """Under the official codes' convention (every light of intensity 1) the bound does not bind:
    the official albedo parameter 0.5 and O's factor 1."""
    bright = dataclasses.replace(
        views,
        lights=[dataclasses.replace(light, intensity=np.full(3, 400.0)) for light in views.lights],
    )
    method = GS3(GS3.resolve_config("mini", num_init_gaussians=300, light_intensity="ignored"))
    method.setup(bright, "cpu", 0)
    assert torch.equal(method.model.attributes["diffuse"], torch.full((300, 3), 0.5))
    assert method.shader.other_scale == 1.0
    assert method.irradiance == pytest.approx(1 / 25, rel=0.35)


# ----------------------------------------------------------------------------------------------
# presets
@pytest.mark.parametrize("method_class", [GaussianSplatting3D, GS3])
@pytest.mark.parametrize("suite", ["nrhints", "gs3", "sssgs", "mini"])
def test_every_suite_has_a_preset(method_class, suite: str) -> None:
    config = method_class.resolve_config(suite)
    assert config.iterations > 0
    half = method_class.resolve_config(suite, iterations=config.iterations // 2)
    assert half.steps(config.densify_until) == pytest.approx(
        config.steps(config.densify_until) / 2, abs=1
    )


def test_gs3_thresholds_scale_with_iterations() -> None:
    config = GS3.resolve_config("gs3", iterations=10_000)
    assert [
        config.steps(v) for v in (config.shadow_from, config.mlp_freeze_from, config.specular_from)
    ] == [500, 900, 1600]


def test_checkpoints_are_checked_for_their_method_and_config(views) -> None:
    gs3 = make_gs3(views)
    splats = GaussianSplatting3D(GaussianSplatting3D.resolve_config("mini", iterations=40, **TINY))
    splats.setup(views, "cpu", 0)
    assert "global_optimizer" not in splats.state_dict()  # 3DGS has no global groups
    with pytest.raises(
        ValueError,
        match=r"not a GS³ checkpoint \(format 'olatbench\.methods\.baselines\.3dgs/2', "
        r"need 'olatbench\.methods\.baselines\.gs3/1'\)",
    ):
        gs3.load_state_dict(splats.state_dict())
    with pytest.raises(
        ValueError, match=r"GS³ checkpoint was written with a different config \(fields: num_asg\)"
    ):
        make_gs3(views, num_asg=2).load_state_dict(gs3.state_dict())
