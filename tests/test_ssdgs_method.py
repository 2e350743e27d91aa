"""SSD-GS end to end on a closed-form scene: schedule gradients, checkpoints, training, every
preset."""

from __future__ import annotations

import io

import numpy as np
import pytest
import torch
from ssdgs_scenes import sphere_views

from olatbench.bench.execute import read_scalars
from olatbench.gaussians.shadow import camera_matched_focal
from olatbench.methods.evaluation_protocol import evaluation_protocol
from olatbench.methods.registry import get_method
from olatbench.methods.ssdgs import SSDGS
from olatbench.methods.ssdgs.presets import ABLATION_PRESETS, SCHEDULE_PRESETS
from olatbench.methods.training import camera_centre

SMALL = {
    "iterations": 1_000,
    "reference_iterations": 100_000,
    "num_init_gaussians": 300,
    "init_radius": 1.3,
    "max_gaussians": 3_000,
    "shadow_resolution": 24,
    "sss_hidden": 32,
    "num_asg": 4,
    "densify_from": 10_000,
    "densify_until": 60_000,
    "opacity_reset_interval": 100_000,
}


@pytest.fixture(scope="module")
def views():
    return sphere_views(4, size=16, seed=1)


def make(views, preset: str | None = None, seed: int = 0, **overrides) -> SSDGS:
    method = SSDGS(SSDGS.resolve_config(preset, **{**SMALL, **overrides}))
    method.setup(views, "cpu", seed)
    return method


def has_grad(params) -> bool:
    return any(p.grad is not None and bool(p.grad.abs().sum() > 0) for p in params)


def clear_grads(method: SSDGS) -> None:
    for p in [*method.model.parameters(), *method.shader.parameters()]:
        p.grad = None


@pytest.mark.parametrize("schedule", ["I", "H", "J", "K"])
def test_gradients_follow_the_schedule(views, schedule: str) -> None:
    method = make(views, f"schedule-{schedule}")
    s = method.schedule
    probes = sorted(
        {
            0,
            *s.enable.values(),
            *(a for w in s.frozen.values() for a, _ in w),
            *(b for w in s.frozen.values() for _, b in w),
            method.config.iterations - 1,
        }
    )
    for step in probes:
        clear_grads(method)
        method.compute_gradients(step, index=0)
        groups = {
            "shadow_mlp": ("shadow", list(method.shader.shadow_net.parameters())),
            "sss_mlp": ("sss", list(method.shader.sss_net.parameters())),
            "asg_lobes": ("specular", list(method.shader.asg.parameters())),
            "specular": (
                "specular",
                [method.model.attributes["specular"], method.model.attributes["asg_weights"]],
            ),
        }
        for group, (term, params) in groups.items():
            expected = s.is_enabled(term, step) and not s.is_frozen(group, step)
            assert has_grad(params) == expected, f"schedule {schedule}, step {step}, group {group}"
        material_expected = (
            s.is_enabled("shadow", step) or s.is_enabled("sss", step)
        ) and not s.is_frozen("material", step)
        assert has_grad([method.model.attributes["material"]]) == material_expected, (
            f"{schedule} {step} material"
        )
        assert has_grad(
            [method.model.attributes["diffuse"], method.model.means, method.model.opacity_logits]
        )


def test_registry_and_resolve_config() -> None:
    assert get_method("ssdgs") is SSDGS
    cfg = SSDGS.resolve_config("mini+ablation-E", iterations=100)
    assert cfg.iterations == 100 and not cfg.use_specular and cfg.use_sss and cfg.use_shadow


def test_save_load_gives_identical_renders_and_resumes_exactly(views) -> None:
    method = make(views, densify_from=200, densify_interval=2)  # densify inside the run
    for step in range(6):
        method.train_step(step + 500)
    buffer = io.BytesIO()
    torch.save(method.state_dict(), buffer)
    buffer.seek(0)
    state = torch.load(buffer, weights_only=True)
    restored = make(views, densify_from=200, densify_interval=2, seed=7)
    restored.load_state_dict(state)
    assert restored.num_gaussians == method.num_gaussians
    a = method.render(views.cameras[1], views.lights[1])
    b = restored.render(views.cameras[1], views.lights[1])
    assert set(a) == {"rgb", "diffuse", "specular", "sss", "shadow", "shadow_coarse", "alpha"}
    for key in a:
        torch.testing.assert_close(a[key], b[key], rtol=0, atol=0)
    torch.manual_seed(3)
    next_a = method.train_step(506)
    torch.manual_seed(3)
    next_b = restored.train_step(506)
    # the step's scalars as the runner reads them
    assert read_scalars(next_a) == read_scalars(next_b)
    with pytest.raises(ValueError, match="different config"):
        make(views, num_asg=2).load_state_dict(state)


def test_a_checkpoint_from_before_a_config_field_existed_restores_when_the_field_is_at_its_default(
    views,
) -> None:
    method = make(views)
    method.train_step(0)
    state = method.state_dict()
    del state["config"]["shadow_input_bias"]  # as written before the field existed
    make(views).load_state_dict(state)  # restores: the default is the old behaviour
    with pytest.raises(ValueError, match=r"different config \(fields: shadow_input_bias\)"):
        make(views, shadow_input_bias="padded_ones").load_state_dict(state)


def test_render_components_are_consistent(views) -> None:
    method = make(views)
    for step in range(3):
        method.train_step(step + 900)  # every term on
    out = method.render(views.cameras[0], views.lights[0])
    assert out["rgb"].shape == (16, 16, 3) and out["shadow"].shape == (16, 16, 1)
    # Splatting is linear in the features: rgb = (diffuse + specular)·S + sss holds per Gaussian,
    # not per pixel, but with S and every component non-negative the unclamped sum bounds the pixel
    # value.
    assert bool(
        (out["diffuse"] >= 0).all() and (out["sss"] >= 0).all() and (out["specular"] >= 0).all()
    )
    assert bool(((out["shadow"] >= 0) & (out["shadow"] <= 1)).all())


@pytest.mark.parametrize("framing", ["camera", "scene"])
def test_light_view_framing(views, framing: str) -> None:
    """ "camera" (default, official) frames the light view at the viewing camera's pixel scale;
    "scene" fits the Gaussians' bounding sphere; both shade with the hint they give."""
    method = make(views, shadow_framing=framing)
    assert SSDGS.resolve_config(None).shadow_framing == "camera"
    tv = method.train_views
    camera_position, light = camera_centre(tv.w2cs[0]), tv.light_positions[0]
    options = method.light_view_options(tv.Ks[0], 16, 16, camera_position, light)
    assert options["resolution"] == 24
    if framing == "camera":
        expected = camera_matched_focal(
            float(tv.Ks[0][0, 0]),
            16,
            24,
            camera_position,
            light,
            method.model.means.detach().mean(0),
        )
        assert options["focal_px"] == pytest.approx(expected)
    else:
        assert options["focal_px"] is None
    for step in range(2):
        # every term on, the hint included
        assert np.isfinite(method.train_step(step + 900)["loss"])
    with pytest.raises(ValueError, match="shadow_framing"):
        SSDGS.resolve_config(None, shadow_framing="fitted")


@pytest.mark.parametrize("preset", [*ABLATION_PRESETS, *SCHEDULE_PRESETS])
def test_every_ablation_and_schedule_preset_trains(views, preset: str) -> None:
    method = make(views, preset)
    losses = [method.train_step(step)["loss"] for step in (0, 400, 999)]
    assert all(np.isfinite(losses))
    out = method.render(views.cameras[0], views.lights[0])
    if not method.config.use_sss:
        assert float(out["sss"].abs().max()) == 0.0
    if not method.config.use_specular:
        assert float(out["specular"].abs().max()) == 0.0


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    return float(-10 * np.log10(np.mean((a - b) ** 2)))


@pytest.mark.slow
def test_short_training_lowers_the_loss_and_beats_a_constant_predictor() -> None:
    train = sphere_views(24, size=24, seed=2)
    test = sphere_views(6, size=24, seed=3)  # other cameras and held-out lights
    method = make(
        train,
        iterations=240,
        reference_iterations=240 * 20,
        init_radius=1.1,
        num_init_gaussians=800,
        densify_from=100 * 20,
        densify_until=200 * 20,
        densify_interval=40,
    )
    losses = [method.train_step(step)["loss"] for step in range(240)]
    assert np.mean(losses[-40:]) < 0.6 * np.mean(losses[:40])
    constant = train.images.reshape(-1, 3).mean(0)
    ours = np.mean(
        [
            _psnr(method.render(c, lt)["rgb"].numpy(), img)
            for c, lt, img in zip(test.cameras, test.lights, test.images, strict=True)
        ]
    )
    baseline = np.mean([_psnr(np.broadcast_to(constant, img.shape), img) for img in test.images])
    assert ours > baseline + 3.0, (ours, baseline)


def test_very_short_mini_runs_train(views) -> None:
    """Scaled densification thresholds never round to 0 (a 5-iteration mini run used to be
    refused)."""
    method = SSDGS(SSDGS.resolve_config("mini", iterations=5, num_init_gaussians=200))
    method.setup(views, "cpu", 0)
    assert all(np.isfinite(method.train_step(step)["loss"]) for step in range(5))


def _pose_error_deg(camera, reference) -> float:
    relative = camera.w2c() @ reference.c2w
    return float(np.degrees(np.arccos(np.clip((np.trace(relative[:3, :3]) - 1) / 2, -1, 1))))


def test_test_time_refinement_recovers_a_perturbed_pose_and_light_with_the_model_frozen() -> None:
    """Target: the model's own render at the true pose/light; start 1.5° / 0.15 units off; model
    untouched."""
    from dataclasses import replace

    from olatbench.gaussians.refinement import so3_exp

    views = sphere_views(6, size=32, seed=1)
    method = make(
        views, refine_camera=True, refine_light=True, test_time_refinement=True, test_time_steps=200
    )
    for step in range(40):
        method.train_step(step)
    camera, light = views.cameras[0], views.lights[0]
    target = method.render(camera, light)["rgb"].numpy()
    delta = np.eye(4)
    delta[:3, :3] = so3_exp(torch.tensor([0.02, -0.015, 0.01], dtype=torch.float64)).numpy()
    delta[:3, 3] = [0.03, -0.02, 0.02]
    start_camera = replace(camera, c2w=np.linalg.inv(delta @ camera.w2c()))
    start_light = replace(light, position=light.position + np.array([0.1, -0.1, 0.05]))
    before = {
        k: v.detach().clone()
        for k, v in [*method.model.state_dict().items(), *method.shader.state_dict().items()]
    }
    refined = method.refine_view(start_camera, start_light, target)
    assert refined.summary["loss_after"] < 0.2 * refined.summary["loss_before"]
    assert _pose_error_deg(refined.camera, camera) < 0.6 * _pose_error_deg(start_camera, camera)
    assert np.linalg.norm(refined.light.position - light.position) < 0.6 * np.linalg.norm(
        start_light.position - light.position
    )
    after = {**method.model.state_dict(), **method.shader.state_dict()}
    assert all(torch.equal(before[k], after[k]) for k in before)
    assert all(p.grad is None for p in [*method.model.parameters(), *method.shader.parameters()])


def test_test_time_refinement_is_off_by_default_and_needs_a_refined_quantity(views) -> None:
    method = make(views)
    assert not evaluation_protocol(method).refines
    assert method.refine_view(views.cameras[0], views.lights[0], views.images[0]) is None
    with pytest.raises(ValueError, match="refine_camera"):
        SSDGS.resolve_config(None, test_time_refinement=True)
