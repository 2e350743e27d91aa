"""The contribution pass (each Gaussian's largest blending weight) against a per-pixel brute force,
C++ against the torch reference, and the property culling relies on: a Gaussian of weight 0 leaves
image and gradients alone."""

from __future__ import annotations

import math

import pytest
import torch
from test_rasterize import covers_tile
from test_rasterize_cpu import projected_inputs
from test_rasterize_scenes import camera, scene

from olatbench.gaussians.backends import cpu_backend_status
from olatbench.gaussians.backends.cpu import max_weights_cpu, rasterize_cpu
from olatbench.gaussians.backends.torch_ref import max_weights_torch, rasterize_torch
from olatbench.gaussians.contribution import max_weights
from olatbench.gaussians.projection import project

D = torch.float64
_STATUS = cpu_backend_status()
needs_cpp = pytest.mark.skipif(not _STATUS[0], reason=f"C++ backend unavailable: {_STATUS[1]}")
SCENES = ("normal", "dense", "offscreen_and_behind", "degenerate_scales")


def brute_force_max_weights(
    means2d, conics, opacities, radii, depths, width, height
) -> torch.Tensor:
    """Per-pixel Python loop over all Gaussians front to back (no tiles, no vectorisation): max of
    T·α."""
    n = len(opacities)
    best = [0.0] * n
    order = sorted(range(n), key=lambda i: (float(depths[i].float()), i))
    m, con, op, r = means2d.tolist(), conics.tolist(), opacities.tolist(), radii.tolist()
    for y in range(height):
        for x in range(width):
            T = 1.0
            for i in order:
                if not covers_tile(m[i], r[i], x // 16, y // 16, width, height):
                    continue
                dx, dy = m[i][0] - (x + 0.5), m[i][1] - (y + 0.5)
                power = -0.5 * (con[i][0] * dx * dx + con[i][2] * dy * dy) - con[i][1] * dx * dy
                if power > 0:
                    continue
                alpha = min(0.99, op[i] * math.exp(power))
                if alpha < 1 / 255:
                    continue
                if T * (1 - alpha) < 1e-4:
                    break
                best[i] = max(best[i], T * alpha)
                T *= 1 - alpha
    return torch.tensor(best, dtype=D)


def inputs(name: str):
    (means2d, conics, opacities, _), bins, radii = projected_inputs(name)
    opacities = opacities.clone()
    opacities[::9] = 0.003  # below 1/255: composited nowhere
    return means2d, conics, opacities, bins, radii


@pytest.mark.parametrize("name", SCENES)
def test_torch_reference_matches_brute_force(name):
    means2d, conics, opacities, bins, radii = inputs(name)
    W, H = bins.width, bins.height
    w2c, K = camera(W, H)
    depths = project(*(scene_tensors(name)), w2c, K, W, H).depths
    expected = brute_force_max_weights(means2d, conics, opacities, radii, depths, W, H)
    got = max_weights_torch(means2d, conics, opacities, bins)
    torch.testing.assert_close(got, expected, rtol=1e-12, atol=1e-14)
    assert int((expected > 0).sum()) >= 3 or name == "degenerate_scales"
    if name == "dense":  # pixels stop early: Gaussians hidden behind them have weight exactly 0
        assert int(((expected == 0) & (radii > 0) & (opacities >= 1 / 255)).sum()) >= 10


def scene_tensors(name: str):
    """means, quats, scales of the `projected_inputs` scene ``name``."""
    from test_rasterize_cpu import SCENES as CPU_SCENES

    cfg = dict(CPU_SCENES[name])
    n = cfg.pop("n")
    cfg.pop("size")
    s = scene(n, **cfg)
    return s["means"], s["quats"], s["scales"]


@needs_cpp
@pytest.mark.parametrize("name", SCENES)
def test_cpp_matches_torch_reference(name):
    means2d, conics, opacities, bins, _ = inputs(name)
    ref = max_weights_torch(means2d, conics, opacities, bins)
    torch.testing.assert_close(
        max_weights_cpu(means2d, conics, opacities, bins), ref, rtol=1e-12, atol=1e-14
    )
    got32 = max_weights_cpu(means2d.float(), conics.float(), opacities.float(), bins)
    assert got32.dtype == torch.float32
    torch.testing.assert_close(got32.double(), ref, rtol=1e-4, atol=1e-5)
    runs = [
        max_weights_cpu(means2d.float(), conics.float(), opacities.float(), bins, threads=t)
        for t in (1, 3)
    ]
    assert torch.equal(runs[0], got32) and torch.equal(runs[1], got32)


@pytest.mark.parametrize("backend", ["torch", pytest.param("cpu", marks=needs_cpp)])
def test_weight_zero_gaussians_do_not_touch_image_or_gradients(backend):
    """Changing the features of every Gaussian of largest weight 0 changes neither the image nor any
    gradient, and their feature gradients are exactly 0: what makes culling at ε = 0 exact."""
    means2d, conics, opacities, bins, _ = inputs("dense")
    features = torch.rand(means2d.shape[0], 3, dtype=D, generator=torch.Generator().manual_seed(2))
    composite = rasterize_torch if backend == "torch" else rasterize_cpu
    unused = max_weights_torch(means2d, conics, opacities, bins) == 0
    assert int(unused.sum()) >= 10

    def run(feats):
        leaves = [t.clone().requires_grad_() for t in (means2d, conics, opacities, feats)]
        colour, final_t = composite(*leaves, bins)
        (colour.square().sum() + final_t.sum()).backward()
        return [colour.detach(), final_t.detach()] + [t.grad for t in leaves]

    base = run(features)
    changed = run(torch.where(unused[:, None], features * 7.0 - 3.0, features))
    for a, b in zip(base, changed, strict=True):
        assert torch.equal(a, b)
    assert torch.equal(base[-1][unused], torch.zeros_like(base[-1][unused]))


def test_public_pass_checks_shapes_and_returns_reusable_bins():
    W, H = 37, 23
    w2c, K = camera(W, H)
    s = scene(40)
    p = project(s["means"], s["quats"], s["scales"], w2c, K, W, H)
    out = max_weights(p, s["opacities"], backend="torch")
    assert out.backend == "torch" and out.max_weight.shape == (40,) and out.bins.width == W
    assert not out.max_weight.requires_grad
    with pytest.raises(ValueError, match="opacities"):
        max_weights(p, s["opacities"][:5])
