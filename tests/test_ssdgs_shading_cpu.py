"""Fused C++ SSD-GS shading (``shading_cpu``) against the torch `Shader`: values, gradients,
gradcheck, float32, thread-count independence and backend dispatch."""

from __future__ import annotations

import itertools
import math

import pytest
import torch

from olatbench import _native
from olatbench.methods.ssdgs.config import SSDGSConfig
from olatbench.methods.ssdgs.shader import Components, Shader
from olatbench.methods.ssdgs.shading_cpu import (
    LIBRARY,
    rotations_cpu,
    shading_combine,
    shading_geometry,
)

_STATUS = LIBRARY.status()
pytestmark = pytest.mark.skipif(
    not _STATUS[0], reason=f"C++ shading kernels unavailable: {_STATUS[1]}"
)

D = torch.float64
TERM_SETS = {
    "none": frozenset(),
    "specular": frozenset({"specular"}),
    "sss": frozenset({"sss"}),
    "shadow": frozenset({"shadow"}),
    "all": frozenset({"specular", "sss", "shadow"}),
}
CAMERA, LIGHT = (0.0, 0.0, -3.0), (0.0, 0.0, 2.0)


def make_shader(dtype: torch.dtype = D, seed: int = 0, **overrides) -> Shader:
    """A small shader with real (narrow) networks and perturbed ASG lobes, in ``dtype``."""
    torch.manual_seed(seed)
    config = SSDGSConfig(
        num_asg=4, sss_hidden=16, sss_layers=3, shadow_hidden=8, shadow_layers=2, **overrides
    )
    shader = Shader(config).to(dtype)
    if config.asg_form == "xu":
        with torch.no_grad():
            shader.asg.rotation.add_(0.4 * torch.randn_like(shader.asg.rotation))
            shader.asg.log_sharpness.add_(0.3 * torch.randn_like(shader.asg.log_sharpness))
    return shader


def make_scene(k: int = 24, dtype: torch.dtype = D, seed: int = 1, edge_cases: bool = True) -> dict:
    """K random Gaussians in the unit ball, then (``edge_cases``) 5 for the camera at (0,0,-3) and
    the light at (0,0,2): (0,0,0) sees camera and light exactly opposite (wi + wo = 0: a zero half
    vector, wi.h = 0, hz = 0); (0,0,-10) sees them in the same direction (wi.h = 1); (0,0,0.5) has a
    normal exactly perpendicular to wi and wo (n.wi = 0, n.wo = 0); two Gaussians have tied smallest
    scales (all three equal; axes 1 and 2)."""
    g = torch.Generator().manual_seed(seed)
    n = k + 5
    positions = torch.randn(n, 3, generator=g, dtype=D)
    positions = (
        positions / positions.norm(dim=-1, keepdim=True) * torch.rand(n, 1, generator=g, dtype=D)
    )
    quats = torch.randn(n, 4, generator=g, dtype=D)
    scales = torch.rand(n, 3, generator=g, dtype=D) + 0.05
    special = k
    positions[special : special + 3] = torch.tensor(
        [[0.0, 0.0, 0.0], [0.0, 0.0, -10.0], [0.0, 0.0, 0.5]], dtype=D
    )
    quats[special + 2] = torch.tensor([1.0, 0.0, 0.0, 0.0], dtype=D)
    scales[special + 2] = torch.tensor([0.1, 1.0, 1.0], dtype=D)
    scales[special + 3] = 0.5
    scales[special + 4] = torch.tensor([1.0, 0.2, 0.2], dtype=D)
    dims = {
        "diffuse": 3,
        "specular": 3,
        "sss": 3,
        "asg_weights": 4,
        "material": 6,
        "shading_quat": 4,
    }
    attributes = {name: torch.randn(n, d, generator=g, dtype=D) for name, d in dims.items()}
    if not edge_cases:
        positions, quats, scales = positions[:k], quats[:k], scales[:k]
        attributes = {name: value[:k] for name, value in attributes.items()}
    scene = {
        "positions": positions,
        "quats": quats,
        "scales": scales,
        "attributes": attributes,
        "camera": torch.tensor(CAMERA, dtype=D),
        "light": torch.tensor(LIGHT, dtype=D),
        "intensity": torch.tensor([3.0, 5.0, 7.0], dtype=D),
        "coarse": torch.rand(n, generator=g, dtype=D)[: positions.shape[0]],
    }
    return cast(scene, dtype)


def cast(scene: dict, dtype: torch.dtype) -> dict:
    """The scene's tensors (and attributes) in ``dtype``."""
    return {
        key: (
            {name: t.to(dtype) for name, t in value.items()}
            if isinstance(value, dict)
            else value.to(dtype)
        )
        for key, value in scene.items()
    }


def shade(
    shader: Shader, scene: dict, terms: frozenset[str], backend: str, seed: int = 7
) -> tuple[Components, dict[str, torch.Tensor | None]]:
    """Components and the gradients of a random linear function of all four colour components w.r.t.
    every input and parameter (None where none flows), on fresh leaves."""
    shader.backend = backend
    shader.zero_grad(set_to_none=True)
    leaves = {
        name: scene[name].clone().requires_grad_(True)
        for name in ("positions", "quats", "camera", "light", "intensity")
    }
    attributes = {
        name: value.clone().requires_grad_(True) for name, value in scene["attributes"].items()
    }
    out = shader(
        leaves["positions"],
        leaves["quats"],
        scene["scales"],
        attributes,
        leaves["camera"],
        leaves["light"],
        leaves["intensity"],
        terms,
        scene["coarse"],
    )
    g = torch.Generator().manual_seed(seed)
    loss = sum(
        (
            getattr(out, name)
            * torch.randn(out.colour.shape, generator=g, dtype=D).to(out.colour.dtype)
        ).sum()
        for name in ("colour", "diffuse", "specular", "sss")
    )
    loss.backward()
    grads = {name: t.grad for name, t in leaves.items()}
    grads.update({f"attribute.{name}": t.grad for name, t in attributes.items()})
    grads.update({f"param.{name}": p.grad for name, p in shader.named_parameters()})
    return out, grads


def assert_relative(
    got: torch.Tensor | None, ref: torch.Tensor | None, rel: float, label: str
) -> None:
    """Both None, or equal up to ``rel`` times the reference's largest magnitude."""
    assert (got is None) == (ref is None), (
        f"{label}: gradient presence differs ({got is None} vs {ref is None})"
    )
    if ref is None:
        return
    assert got.shape == ref.shape and got.dtype == ref.dtype, label
    scale = float(ref.abs().max())
    error = float((got - ref).abs().max())
    assert error <= rel * scale or (scale == 0.0 and error == 0.0), (
        f"{label}: max |Δ| {error:.3e}, scale {scale:.3e}"
    )


COMBOS = list(
    itertools.product(
        ["smooth", "clamped"],
        ["min_scale", "learned"],
        [True, False],
        sorted(TERM_SETS),
        [False, True],
    )
)


@pytest.mark.parametrize(("cosine", "frame", "orient", "terms", "shadow_on_sss"), COMBOS)
def test_float64_matches_torch_shader(cosine, frame, orient, terms, shadow_on_sss):
    shader = make_shader(
        diffuse_cosine=cosine,
        shading_frame=frame,
        orient_normals=orient,
        shadow_on_sss=shadow_on_sss,
    )
    scene = make_scene()
    ref, ref_grads = shade(shader, scene, TERM_SETS[terms], "torch")
    got, got_grads = shade(shader, scene, TERM_SETS[terms], "cpu")
    # the fused path ran
    assert type(got.colour.grad_fn).__name__ != type(ref.colour.grad_fn).__name__
    for name in ("colour", "diffuse", "specular", "sss", "shadow", "shadow_coarse"):
        assert_relative(getattr(got, name).detach(), getattr(ref, name).detach(), 1e-12, name)
    assert got_grads.keys() == ref_grads.keys()
    for name, ref_grad in ref_grads.items():
        assert_relative(got_grads[name], ref_grad, 1e-10, name)
    if terms == "all" and frame == "min_scale":
        assert ref_grads["quats"] is not None and ref_grads["param.asg.rotation"] is not None


def test_edge_cases_are_exercised():
    """The scene's special Gaussians hit the boundaries the comparison above is meant to cover."""
    scene = make_scene()
    k = 24
    wi, wo, frames, _ = shading_geometry(
        scene["positions"],
        scene["quats"],
        scene["scales"],
        scene["camera"],
        scene["light"],
        orient_normals=True,
    )
    assert torch.equal(wi[k] + wo[k], torch.zeros(3, dtype=D))  # opposite: zero half vector
    assert torch.equal(wi[k + 1], wo[k + 1])  # same direction: wi.h = 1
    assert (
        float((frames[k + 2, :, 2] * wi[k + 2]).sum())
        == 0.0
        == float((frames[k + 2, :, 2] * wo[k + 2]).sum())
    )
    assert bool(((frames[:, :, 2] * wo).sum(-1) >= 0).all())  # oriented
    unoriented = shading_geometry(
        scene["positions"],
        scene["quats"],
        scene["scales"],
        scene["camera"],
        scene["light"],
        orient_normals=False,
    )[2]
    assert bool(((unoriented[:, :, 2] * wo).sum(-1) < 0).any())  # some Gaussians were back-facing


def test_geometry_gradcheck():
    g = torch.Generator().manual_seed(3)
    positions = torch.randn(6, 3, generator=g, dtype=D).requires_grad_()
    quats = torch.randn(6, 4, generator=g, dtype=D).requires_grad_()
    scales = torch.rand(6, 3, generator=g, dtype=D)
    camera = torch.tensor([0.3, -2.5, 1.0], dtype=D, requires_grad=True)
    light = torch.tensor([2.0, -1.0, 2.5], dtype=D, requires_grad=True)
    for scale_arg, orient in itertools.product([scales, None], [True, False]):

        def fn(p, q, c, light_position, scale_arg=scale_arg, orient=orient):
            return shading_geometry(p, q, scale_arg, c, light_position, orient_normals=orient)

        assert torch.autograd.gradcheck(fn, (positions, quats, camera, light))


@pytest.mark.parametrize(
    ("cosine", "shadow_on_sss", "profile_channels"),
    [("smooth", False, 1), ("clamped", True, 3), ("smooth", True, 3)],
)
def test_combine_gradcheck(cosine, shadow_on_sss, profile_channels):
    g = torch.Generator().manual_seed(4)
    k, n_lobes = 5, 3

    def rand(*shape, positive=False):
        t = (
            torch.rand(*shape, generator=g, dtype=D) + 0.5
            if positive
            else torch.randn(*shape, generator=g, dtype=D)
        )
        return t.requires_grad_()

    wi, wo = rand(k, 3), rand(k, 3)
    frames, inv_dist2, intensity = rand(k, 3, 3), rand(k, 1, positive=True), rand(3, positive=True)
    raw = {
        name: rand(k, d)
        for name, d in (("diffuse", 3), ("specular", 3), ("asg_weights", n_lobes), ("sss", 3))
    }
    lobe_axes, lam, mu = (
        rand(n_lobes, 3, 3),
        rand(n_lobes, positive=True),
        rand(n_lobes, positive=True),
    )
    profile, shadow = rand(k, profile_channels, positive=True), rand(k, 1, positive=True)

    def fn(*args):
        (
            wi_,
            wo_,
            frames_,
            inv_,
            intensity_,
            diffuse,
            specular,
            weights,
            sss,
            axes,
            lam_,
            mu_,
            profile_,
            shadow_,
        ) = args
        return shading_combine(
            wi_,
            wo_,
            frames_,
            inv_,
            intensity_,
            diffuse,
            specular=specular,
            asg_weights=weights,
            lobe_axes=axes,
            lam=lam_,
            mu=mu_,
            sss=sss,
            profile=profile_,
            shadow=shadow_,
            diffuse_cosine=cosine,
            shadow_on_sss=shadow_on_sss,
        )

    inputs = (
        wi,
        wo,
        frames,
        inv_dist2,
        intensity,
        raw["diffuse"],
        raw["specular"],
        raw["asg_weights"],
        raw["sss"],
        lobe_axes,
        lam,
        mu,
        profile,
        shadow,
    )
    assert torch.autograd.gradcheck(fn, inputs)


def test_combine_gradcheck_terms_off():
    g = torch.Generator().manual_seed(5)
    wi, wo, frames, diffuse = (
        torch.randn(*s, generator=g, dtype=D).requires_grad_()
        for s in ((4, 3), (4, 3), (4, 3, 3), (4, 3))
    )
    inv_dist2 = (torch.rand(4, 1, generator=g, dtype=D) + 0.5).requires_grad_()
    intensity = (torch.rand(3, generator=g, dtype=D) + 0.5).requires_grad_()
    assert torch.autograd.gradcheck(
        lambda *a: shading_combine(*a, diffuse_cosine="clamped"),
        (wi, wo, frames, inv_dist2, intensity, diffuse),
    )
    colour, diffuse_out, specular, sss = shading_combine(
        wi, wo, frames, inv_dist2, intensity, diffuse
    )
    assert torch.equal(specular, torch.zeros_like(specular)) and torch.equal(
        sss, torch.zeros_like(sss)
    )
    torch.testing.assert_close(colour, diffuse_out, rtol=0, atol=0)


def test_rotations_match_quat_to_rotmat():
    from olatbench.gaussians.projection import quat_to_rotmat

    quats = torch.randn(7, 4, generator=torch.Generator().manual_seed(6), dtype=D).requires_grad_()
    torch.testing.assert_close(rotations_cpu(quats), quat_to_rotmat(quats), rtol=1e-14, atol=1e-15)
    assert torch.autograd.gradcheck(rotations_cpu, (quats,))


def test_float32_matches_torch_shader():
    """float32: outputs within 1e-5 and gradients within 1e-4 of torch's float32 (sharp ASG lobes
    amplify the rounding of exp's argument), and no further than torch's float32 from the float64
    result."""
    shader = make_shader(torch.float32)
    scene = make_scene(k=300, dtype=torch.float32)
    terms = TERM_SETS["all"]
    ref, ref_grads = shade(shader, scene, terms, "torch")
    got, got_grads = shade(shader, scene, terms, "cpu")
    _, exact_grads = shade(make_shader(D), cast(scene, D), terms, "cpu")
    assert got.colour.dtype == torch.float32
    for name in ("colour", "diffuse", "specular", "sss"):
        assert_relative(getattr(got, name).detach(), getattr(ref, name).detach(), 1e-5, name)
    for name, ref_grad in ref_grads.items():
        assert_relative(got_grads[name], ref_grad, 1e-4, name)
        if ref_grad is not None:
            scale = float(exact_grads[name].abs().max())
            error_cpu = float((got_grads[name].double() - exact_grads[name]).abs().max())
            error_torch = float((ref_grad.double() - exact_grads[name]).abs().max())
            assert error_cpu <= 2 * error_torch + 1e-6 * scale, (
                f"{name}: {error_cpu:.2e} vs torch {error_torch:.2e}"
            )


def kernel_outputs(threads: int, dtype: torch.dtype):
    """Forward outputs and all gradients of both kernels on 1000 Gaussians
    (several reduction blocks)."""
    scene = make_scene(k=995, dtype=dtype, seed=9)
    shader = make_shader(dtype)
    leaves = [
        t.clone().requires_grad_()
        for t in (scene["positions"], scene["quats"], scene["camera"], scene["light"])
    ]
    geometry = shading_geometry(
        leaves[0], leaves[1], scene["scales"], leaves[2], leaves[3], True, threads=threads
    )
    g = torch.Generator().manual_seed(2)
    n = scene["positions"].shape[0]
    extra = [torch.rand(n, 1, generator=g, dtype=D).to(dtype).requires_grad_() for _ in range(2)]
    attributes = {
        name: value.clone().requires_grad_() for name, value in scene["attributes"].items()
    }
    lam, mu = shader.asg.log_sharpness.exp().unbind(-1)
    out = shading_combine(
        *geometry,
        scene["intensity"],
        attributes["diffuse"],
        specular=attributes["specular"],
        asg_weights=attributes["asg_weights"],
        lobe_axes=shader.asg.frames(),
        lam=lam,
        mu=mu,
        sss=attributes["sss"],
        profile=extra[0],
        shadow=extra[1],
        threads=threads,
    )
    loss = sum((o * torch.randn(o.shape, generator=g, dtype=D).to(dtype)).sum() for o in out)
    inputs = [*leaves, *extra, *attributes.values(), *shader.asg.parameters()]
    grads = torch.autograd.grad(loss, inputs, allow_unused=True)
    return [*geometry, *out, *(t for t in grads if t is not None)]


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_results_do_not_depend_on_threads(dtype):
    one, two = kernel_outputs(1, dtype), kernel_outputs(2, dtype)
    assert len(one) == len(two)
    for a, b in zip(one, two, strict=True):
        assert torch.equal(a, b)


def test_results_do_not_depend_on_threads_when_the_caller_flushes_denormals():
    """OpenMP workers run in the calling thread's float mode: with torch.set_flush_denormal(True)
    set after the workers exist (e.g. by a training script), a worker that kept its own mode
    computed denormals the caller flushes, and results changed with the thread count."""
    plain = kernel_outputs(2, torch.float32)  # creates the workers in the default mode
    try:
        assert torch.set_flush_denormal(True)
        one, two = kernel_outputs(1, torch.float32), kernel_outputs(2, torch.float32)
    finally:
        torch.set_flush_denormal(False)
    # these inputs do meet denormals
    assert any(not torch.equal(a, b) for a, b in zip(plain, one, strict=True))
    for a, b in zip(one, two, strict=True):
        assert torch.equal(a, b)


def test_cpu_backend_rejects_the_official_asg_form_and_auto_falls_back():
    shader = make_shader(asg_form="official")
    # the official form's torch gradient is NaN at a zero half vector
    scene = make_scene(edge_cases=False)
    terms = TERM_SETS["all"]
    with pytest.raises(ValueError, match=r"asg_form 'official'.*'xu'"):
        shade(shader, scene, terms, "cpu")
    ref, ref_grads = shade(shader, scene, terms, "torch")
    got, got_grads = shade(shader, scene, terms, "auto")
    # the torch path ran
    assert type(got.colour.grad_fn).__name__ == type(ref.colour.grad_fn).__name__
    assert torch.equal(got.colour, ref.colour)
    # (autograd may sum a leaf's gradient contributions in another order)
    for name, ref_grad in ref_grads.items():
        assert_relative(got_grads[name], ref_grad, 1e-14, name)


def test_backend_validation_and_unsupported_inputs():
    with pytest.raises(ValueError, match="backend must be one of"):
        Shader(SSDGSConfig(), backend="gpu")
    shader = make_shader()
    scene = make_scene()
    scene["intensity"] = scene["intensity"].float()  # mixed dtypes
    with pytest.raises(ValueError, match="different dtypes"):
        shade(shader, scene, TERM_SETS["all"], "cpu")
    out, _ = shade(shader, scene, TERM_SETS["all"], "auto")  # the torch path promotes as before
    assert out.colour.dtype == D


def test_shadow_term_needs_coarse_visibility():
    shader = make_shader()
    scene = make_scene()
    shader.backend = "cpu"
    with pytest.raises(ValueError, match="coarse light-view visibility"):
        shader(
            scene["positions"],
            scene["quats"],
            scene["scales"],
            scene["attributes"],
            scene["camera"],
            scene["light"],
            scene["intensity"],
            TERM_SETS["shadow"],
        )


def test_degenerate_distances_match_torch():
    """A Gaussian at the light (d² clamped at 1e-12) and one at the camera (|c - p| below the
    normalisation eps)."""
    shader = make_shader()
    scene = make_scene(k=4)
    scene["positions"][0] = scene["light"]
    scene["positions"][1] = scene["camera"]
    for cosine in ("smooth", "clamped"):
        shader.config.diffuse_cosine = cosine
        ref, ref_grads = shade(shader, scene, TERM_SETS["all"], "torch")
        got, got_grads = shade(shader, scene, TERM_SETS["all"], "cpu")
        assert math.isfinite(float(got.colour.detach().abs().max()))
        for name in ("colour", "diffuse", "specular", "sss"):
            assert_relative(getattr(got, name).detach(), getattr(ref, name).detach(), 1e-12, name)
        for name, ref_grad in ref_grads.items():
            assert_relative(got_grads[name], ref_grad, 1e-10, name)


def test_failed_build_shades_with_torch_after_one_warning(monkeypatch, tmp_path):
    """auto: a C++ library that cannot be built gives the torch shading and one RuntimeWarning
    saying why; an explicit "cpu" request fails with that reason instead (RuntimeError: the backend
    is missing)."""
    import warnings

    shader, scene = make_shader(), make_scene(edge_cases=False)
    reference, _ = shade(shader, scene, TERM_SETS["all"], "torch")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setenv("OLATBENCH_CXX", str(tmp_path / "no-such-compiler"))
    _native.reset_fallback_warnings()
    LIBRARY.reset()
    try:
        with pytest.warns(
            RuntimeWarning,
            match=r"SSD-GS shading backend 'cpu' is unavailable, falling back.*no-such",
        ):
            out, _ = shade(shader, scene, TERM_SETS["all"], "auto")
        assert torch.equal(out.colour, reference.colour)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            shade(shader, scene, TERM_SETS["all"], "auto")  # once per process
        with pytest.raises(
            RuntimeError, match=r"C\+\+ library olatbench_ssdgs_shading is unavailable.*no-such"
        ):
            shade(shader, scene, TERM_SETS["all"], "cpu")
    finally:
        LIBRARY.reset()
        _native.reset_fallback_warnings()
