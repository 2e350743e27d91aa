"""Contribution culling in SSD-GS and GS³: exact at ε = 0, bounded at the default ε
(docs/ssdgs.md)."""

from __future__ import annotations

import math

import pytest
import torch
from ssdgs_scenes import sphere_views

from olatbench.gaussians.contribution import max_weights
from olatbench.gaussians.rasterize import rasterize
from olatbench.methods.baselines.gs3 import GS3
from olatbench.methods.shading.config import ShadingConfig
from olatbench.methods.ssdgs import SSDGS
from olatbench.methods.ssdgs.config import SSDGSConfig
from olatbench.methods.training import VisibleSubset

SMALL = {
    "iterations": 1_000,
    "reference_iterations": 100_000,
    "num_init_gaussians": 600,
    "init_radius": 1.3,
    "max_gaussians": 3_000,
    "shadow_resolution": 24,
    "sss_hidden": 32,
    "num_asg": 4,
    "densify_from": 10_000,
    "densify_until": 60_000,
    "opacity_reset_interval": 100_000,
}
GS3_SMALL = {
    "iterations": 100,
    "reference_iterations": 100,
    "shadow_from": 5,
    "mlp_freeze_from": 20,
    "specular_from": 30,
    "asg_lobes_from": 40,
    "shadow_resolution": 24,
    "other_hidden": 16,
    "num_asg": 4,
    "num_init_gaussians": 600,
    "init_radius": 1.3,
    "max_gaussians": 2_000,
    "densify_from": 100_000,
    "densify_until": 100_000,
    "opacity_reset_interval": 100_000,
}
SSDGS_ALL_ON, GS3_ALL_ON = 999, 45  # every term on, nothing frozen
# float32 rounding of the networks' batched products, which depends on the batch (culled or not), at
# most 3e-7 of each gradient's largest entry here; any Gaussian wrongly culled shows as ~1e-3
# (see the ε > 0 test).
ROUNDING = 1e-5


@pytest.fixture(scope="module")
def views():
    return sphere_views(3, size=32, seed=1, background=0.3)  # grey: T_final enters the loss


def on_surface(method, radius: float = 1.0, opacity: float = 0.9) -> None:
    """A closed opaque surface (Gaussians on a sphere, flat along its normal): many hide behind
    stopped pixels."""
    model = method.model
    n = model.num_gaussians
    normals = torch.nn.functional.normalize(
        torch.randn(n, 3, generator=torch.Generator().manual_seed(0)), dim=-1
    )
    tangent = 1.5 * math.sqrt(4.0 * math.pi * radius**2 / n)
    z = torch.tensor([0.0, 0.0, 1.0])
    # the rotation taking +z to the normal (wxyz)
    half = torch.nn.functional.normalize(normals + z, dim=-1)
    with torch.no_grad():
        model.quats.copy_(
            torch.cat([half[:, 2:3], torch.linalg.cross(z.expand(n, 3), half)], dim=1)
        )
        model.means.copy_(normals * radius)
        model.log_scales.copy_(torch.log(torch.tensor([tangent, tangent, 0.1 * tangent])))
        model.opacity_logits.fill_(math.log(opacity / (1.0 - opacity)))


def make(method_class, views, **overrides):
    values = SMALL if method_class is SSDGS else GS3_SMALL
    method = method_class(method_class.resolve_config(None, **{**values, **overrides}))
    method.setup(views, "cpu", 0)
    on_surface(method)
    return method


def image_and_grads(method, step: int) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """The training forward's image and every parameter's gradient of the training loss on view
    0."""
    modules = (method.model, method.shader)
    for module in modules:
        module.zero_grad(set_to_none=True)
    with torch.no_grad():
        image = method.training_forward(0, step)["image"]
    method.compute_gradients(step, index=0)
    grads = {
        name: p.grad.clone()
        for module in modules
        for name, p in module.named_parameters()
        if p.grad is not None
    }
    return image, grads


def shaded_count(method, epsilon: float) -> tuple[int, int]:
    """(Gaussians above ``epsilon``, visible Gaussians) of training view 0."""
    from olatbench.gaussians.projection import project

    views, model = method.train_views, method.model
    camera = views.views.cameras[0]
    p = project(
        model.means,
        model.quats,
        model.scales,
        views.w2cs[0],
        views.Ks[0],
        camera.width,
        camera.height,
    )
    return int((max_weights(p, model.opacities).max_weight > epsilon).sum()), int(
        (p.radii > 0).sum()
    )


@pytest.mark.parametrize(
    ("method_class", "step", "exact"),
    [(SSDGS, 0, True), (SSDGS, SSDGS_ALL_ON, False), (GS3, 0, True), (GS3, GS3_ALL_ON, False)],
)
def test_culling_at_zero_is_exact(views, method_class, step, exact):
    """ε = 0: the same image and gradients. Bit for bit with the closed-form shading alone (the
    first steps: diffuse only); up to the networks' batch-dependent float32 rounding once they
    run."""
    plain = make(method_class, views)
    culled = make(method_class, views, cull_shading=True, cull_epsilon=0.0)
    shaded, visible = shaded_count(culled, 0.0)
    assert shaded < 0.95 * visible  # the test culls something
    image, grads = image_and_grads(plain, step)
    culled_image, culled_grads = image_and_grads(culled, step)
    assert set(grads) == set(culled_grads)
    if exact:
        assert torch.equal(culled_image, image)
        for name, grad in grads.items():
            assert torch.equal(culled_grads[name], grad), name
        return
    torch.testing.assert_close(
        culled_image, image, rtol=0.0, atol=ROUNDING * float(image.abs().max())
    )
    for name, grad in grads.items():
        torch.testing.assert_close(
            culled_grads[name],
            grad,
            rtol=0.0,
            atol=ROUNDING * float(grad.abs().max()),
            msg=lambda m, name=name: f"{name}: {m}",
        )


def test_default_epsilon_bounds_image_and_gradient_changes(views):
    """At the default ε: the image changes by exactly the culled Gaussians' own contribution (their
    geometry and so every weight is unchanged), under 0.1 of an 8-bit level; culled Gaussians get no
    gradient on their shading attributes but keep one on their geometry; every gradient moves by at
    most 0.1 % of its largest entry."""
    epsilon = SSDGSConfig().cull_epsilon
    plain = make(SSDGS, views)
    culled = make(SSDGS, views, cull_shading=True)
    image, grads = image_and_grads(plain, SSDGS_ALL_ON)
    culled_image, culled_grads = image_and_grads(culled, SSDGS_ALL_ON)

    out = plain.training_forward(0, SSDGS_ALL_ON)
    projected, model = out["projected"], plain.model
    weights = max_weights(projected, model.opacities).max_weight
    dropped = (projected.radii > 0) & (weights <= epsilon)
    assert int(dropped.sum()) >= 50
    # the culled Gaussians' colours alone, composited with the unchanged weights, make up the
    # difference
    colours = plain_colours(plain, SSDGS_ALL_ON)
    missing = rasterize(
        projected, model.opacities, torch.where(dropped[:, None], colours, 0.0), torch.zeros(3)
    ).image
    torch.testing.assert_close(image - culled_image, missing.detach(), rtol=0.0, atol=1e-6)
    assert 0.0 < float((image - culled_image).abs().max()) < 0.1 / 255

    attributes = [name for name in culled_grads if name.startswith("attributes.")]
    assert attributes
    for name in attributes:
        assert torch.equal(
            culled_grads[name][dropped], torch.zeros_like(culled_grads[name][dropped])
        ), name
    # culled yet composited: their geometry still gets compositing gradients
    faint = dropped & (weights > 0)
    assert int(faint.sum()) >= 10
    for name in ("means", "opacity_logits", "log_scales"):
        assert bool(
            (culled_grads[name][faint].reshape(int(faint.sum()), -1).abs().amax(1) > 0).all()
        ), name
    for name, grad in grads.items():
        change = float((culled_grads[name] - grad).abs().max()) / float(grad.abs().max())
        assert change < 1e-3, f"{name}: {change:.2e}"


def plain_colours(method: SSDGS, step: int) -> torch.Tensor:
    """Every Gaussian's shaded colour (N, 3) as the unculled training forward computes it
    (0 if not visible)."""
    captured = {}
    shader = method.shader
    original = shader.forward

    def capture(*args, **kwargs):
        captured["out"] = original(*args, **kwargs)
        return captured["out"]

    shader.forward = capture
    try:
        with torch.no_grad():
            radii = method.training_forward(0, step)["projected"].radii
    finally:
        del shader.forward
    return VisibleSubset(radii).scatter(captured["out"].colour)


def test_cull_config_is_checked_and_defaults_off():
    assert ShadingConfig().cull_shading is False
    assert SSDGSConfig().shading_cull_epsilon(evaluation=False) is None
    on = SSDGSConfig(cull_shading=True, cull_epsilon=0.01)
    assert (
        on.shading_cull_epsilon(evaluation=False),
        on.shading_cull_epsilon(evaluation=True),
    ) == (0.01, 0.0)
    with pytest.raises(ValueError, match="cull_epsilon"):
        SSDGSConfig(cull_epsilon=-1e-3)
