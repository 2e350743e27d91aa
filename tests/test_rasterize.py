"""Torch reference rasterizer: brute-force per-pixel compositing, tile binning, and finite
differences."""

from __future__ import annotations

import itertools
import math

import pytest
import torch
from test_rasterize_scenes import camera, scene

from olatbench.gaussians.projection import project
from olatbench.gaussians.rasterize import rasterize
from olatbench.gaussians.render import render
from olatbench.gaussians.tiles import bin_gaussians

D = torch.float64
NAMES = ("means", "quats", "scales", "opacities", "features", "background")


def covers_tile(
    mean: list[float], radius: int, tx: int, ty: int, width: int, height: int, tile: int = 16
) -> bool:
    """Documented binning rule: the pixels whose centres lie within mean ± radius touch tile
    (tx, ty)."""
    x_lo, x_hi = math.ceil(mean[0] - radius - 0.5), math.floor(mean[0] + radius - 0.5)
    y_lo, y_hi = math.ceil(mean[1] - radius - 0.5), math.floor(mean[1] + radius - 0.5)
    x_lo, x_hi = max(x_lo, tx * tile, 0), min(x_hi, (tx + 1) * tile - 1, width - 1)
    y_lo, y_hi = max(y_lo, ty * tile, 0), min(y_hi, (ty + 1) * tile - 1, height - 1)
    return radius > 0 and x_lo <= x_hi and y_lo <= y_hi


def brute_force(p, opacities, features, background, return_depth=False):
    """Per-pixel Python loop over the depth-sorted Gaussians of the pixel's tile (no vectorisation).

    Returns image, alpha, depth and the number of pixels that terminated early
    (T would drop below 1e-4)."""
    H, W = p.height, p.width
    C = features.shape[1]
    image = torch.zeros(H, W, C, dtype=D)
    alpha_img = torch.zeros(H, W, dtype=D)
    depth_img = torch.zeros(H, W, dtype=D)
    stopped = 0
    order = sorted(range(len(opacities)), key=lambda i: (float(p.depths[i].float()), i))
    means, conics, radii = p.means2d.tolist(), p.conics.tolist(), p.radii.tolist()
    for y in range(H):
        for x in range(W):
            T, colour, depth = 1.0, torch.zeros(C, dtype=D), 0.0
            for i in order:
                if not covers_tile(means[i], radii[i], x // 16, y // 16, W, H):
                    continue
                dx, dy = means[i][0] - (x + 0.5), means[i][1] - (y + 0.5)
                a, b, c = conics[i]
                power = -0.5 * (a * dx * dx + c * dy * dy) - b * dx * dy
                if power > 0:
                    continue
                alpha = min(0.99, float(opacities[i]) * math.exp(power))
                if alpha < 1 / 255:
                    continue
                if T * (1 - alpha) < 1e-4:
                    stopped += 1
                    break
                colour += T * alpha * features[i]
                depth += T * alpha * float(p.depths[i])
                T *= 1 - alpha
            image[y, x] = colour + T * background
            alpha_img[y, x] = 1 - T
            depth_img[y, x] = depth / (1 - T) if 1 - T > 1e-8 else 0.0
    return image, alpha_img, depth_img, stopped


@pytest.mark.parametrize(
    ("n", "size", "kwargs"),
    [
        (25, (37, 23), {}),
        # dense: pixels terminate early
        (150, (20, 18), {"opacity": (0.6, 0.99), "scale": (0.05, 0.2)}),
        (30, (33, 17), {"spread": 1.5, "depth": 1.0}),  # partly off-screen and behind the camera
    ],
)
def test_reference_matches_brute_force(n, size, kwargs):
    W, H = size
    w2c, K = camera(W, H)
    s = scene(n, **kwargs)
    p = project(s["means"], s["quats"], s["scales"], w2c, K, W, H)
    out = rasterize(
        p, s["opacities"], s["features"], s["background"], backend="torch", return_depth=True
    )
    image, alpha, depth, stopped = brute_force(p, s["opacities"], s["features"], s["background"])
    torch.testing.assert_close(out.image, image, rtol=1e-10, atol=1e-12)
    torch.testing.assert_close(out.alpha, alpha, rtol=1e-10, atol=1e-12)
    torch.testing.assert_close(out.depth, depth, rtol=1e-10, atol=1e-10)
    if kwargs.get("opacity"):
        assert stopped > 20  # early termination was exercised


def test_bins_hold_the_covering_gaussians_front_to_back():
    W, H = 53, 37
    w2c, K = camera(W, H)
    s = scene(60, spread=1.0)
    p = project(s["means"], s["quats"], s["scales"], w2c, K, W, H)
    bins = bin_gaussians(p.means2d, p.radii, p.depths, W, H)
    assert (bins.tiles_x, bins.tiles_y) == (4, 3)
    means, radii = p.means2d.tolist(), p.radii.tolist()
    for t in range(bins.num_tiles):
        ids = bins.gaussian_ids[bins.offsets[t] : bins.offsets[t + 1]].tolist()
        expected = {i for i in range(60) if covers_tile(means[i], radii[i], t % 4, t // 4, W, H)}
        assert set(ids) == expected and len(ids) == len(expected)
        assert all(p.depths[i] <= p.depths[j] for i, j in itertools.pairwise(ids))


def test_negative_and_tied_sort_keys_order():
    means2d = torch.full((4, 2), 8.0)
    radii = torch.full((4,), 3)
    bins = bin_gaussians(means2d, radii, torch.tensor([0.5, -2.0, 0.5, -0.1]), 16, 16)
    assert bins.gaussian_ids.tolist() == [1, 3, 0, 2]


@pytest.mark.parametrize("backend", ["torch", "cpu"])
@pytest.mark.parametrize("n", [0, 4])
def test_empty_scene_is_background(backend, n):
    W, H = 19, 11
    w2c, K = camera(W, H)
    s = scene(n, depth=-3.0)  # none, or all behind the camera
    s["means"].requires_grad_()
    out = render(s["means"], s["quats"], s["scales"], s["opacities"], s["features"], w2c, K, W, H,
                 s["background"], backend=backend, return_depth=True)  # fmt: skip
    assert not out["visible"].any()
    torch.testing.assert_close(out["image"].detach(), s["background"].expand(H, W, -1))
    assert out["alpha"].abs().max() == 0 and out["depth"].abs().max() == 0
    out["image"].sum().backward()
    assert s["means"].grad.abs().sum() == 0


def render_loss(backend: str, W: int, H: int, K: torch.Tensor, seed: int = 1):
    g = torch.Generator().manual_seed(seed)
    wi, wa, wd = (torch.rand(H, W, *shape, generator=g, dtype=D) for shape in ((3,), (), ()))

    def loss(means, quats, scales, opacities, features, background, w2c):
        out = render(
            means,
            quats,
            scales,
            opacities,
            features,
            w2c,
            K,
            W,
            H,
            background,
            backend=backend,
            return_depth=True,
        )
        return (
            (out["image"] * wi).sum() + (out["alpha"] * wa).sum() + 0.1 * (out["depth"] * wd).sum()
        )

    return loss


@pytest.mark.parametrize("backend", ["torch", "cpu"])
def test_render_gradients_match_finite_differences(backend):
    """Central differences in float64 for every input: means, quats, scales, opacities, features,
    background, pose."""
    W, H = 20, 14
    w2c, K = camera(W, H)
    s = scene(6, spread=0.3)
    inputs = [s[k].clone().requires_grad_() for k in NAMES] + [w2c.clone().requires_grad_()]
    assert torch.autograd.gradcheck(
        render_loss(backend, W, H, K), inputs, eps=1e-6, atol=1e-6, rtol=1e-5
    )


def test_gradients_reach_every_input_and_retained_means2d():
    W, H = 24, 20
    w2c, K = camera(W, H)
    s = {k: v.float().requires_grad_() for k, v in scene(6, spread=0.3).items()}
    out = render(
        s["means"],
        s["quats"],
        s["scales"],
        s["opacities"],
        s["features"],
        w2c.float(),
        K.float(),
        W,
        H,
        s["background"],
        backend="torch",
    )
    out["means2d"].retain_grad()
    out["image"].sum().backward()
    assert out["means2d"].grad.abs().sum() > 0
    for name in NAMES:
        assert s[name].grad is not None and s[name].grad.abs().sum() > 0, name
