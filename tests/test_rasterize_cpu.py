"""C++ CPU backend against the torch reference (values and gradients), determinism, and the
light-view pass."""

from __future__ import annotations

import functools
import math

import pytest
import torch
from test_rasterize_scenes import camera, scene

from olatbench.gaussians.backends import cpu_backend_status
from olatbench.gaussians.backends.cpu import rasterize_cpu, shadow_gather_cpu
from olatbench.gaussians.backends.torch_ref import rasterize_torch
from olatbench.gaussians.compositing import GSPLAT
from olatbench.gaussians.projection import project
from olatbench.gaussians.rasterize import rasterize
from olatbench.gaussians.tiles import bin_gaussians

D = torch.float64
_STATUS = cpu_backend_status()
pytestmark = pytest.mark.skipif(not _STATUS[0], reason=f"C++ backend unavailable: {_STATUS[1]}")

SCENES = {
    "normal": dict(n=40, size=(37, 23)),
    "dense": dict(n=300, size=(21, 19), opacity=(0.5, 0.99), scale=(0.05, 0.25)),
    "offscreen_and_behind": dict(n=40, size=(37, 23), spread=1.6, depth=1.0),
    "degenerate_scales": dict(n=30, size=(33, 17), scale=(1e-9, 1e-7)),
    "one_channel": dict(n=30, size=(37, 23), channels=1),
    "twelve_channels": dict(n=30, size=(37, 23), channels=12),
}


def projected_inputs(name: str, dtype: torch.dtype = D):
    cfg = dict(SCENES[name])
    n, (W, H) = cfg.pop("n"), cfg.pop("size")
    w2c, K = camera(W, H)
    s = scene(n, **cfg)
    p = project(s["means"], s["quats"], s["scales"], w2c, K, W, H)
    bins = bin_gaussians(p.means2d, p.radii, p.depths, W, H)
    leaves = [p.means2d.detach(), p.conics.detach(), s["opacities"], s["features"]]
    return [t.to(dtype) for t in leaves], bins, p.radii


def values_and_grads(fn, leaves, bins, seed=5):
    leaves = [t.clone().requires_grad_() for t in leaves]
    colour, final_t = fn(*leaves, bins)
    g = torch.Generator().manual_seed(seed)
    w_colour = torch.randn(colour.shape, generator=g, dtype=D).to(colour.dtype)
    w_t = torch.randn(final_t.shape, generator=g, dtype=D).to(final_t.dtype)
    ((colour * w_colour).sum() + (final_t * w_t).sum()).backward()
    return [colour.detach(), final_t.detach()] + [t.grad for t in leaves]


@pytest.mark.parametrize("name", sorted(SCENES))
def test_cpu_float64_matches_reference(name):
    leaves, bins, _ = projected_inputs(name)
    ref = values_and_grads(rasterize_torch, leaves, bins)
    got = values_and_grads(rasterize_cpu, leaves, bins)
    for label, r, c in zip(
        ["colour", "T", "means2d", "conics", "opacities", "features"], ref, got, strict=True
    ):
        torch.testing.assert_close(
            c, r, rtol=1e-9, atol=1e-11, msg=lambda m, label=label: f"{name}/{label}: {m}"
        )
    if name == "dense":
        assert float(got[1].min()) < 2e-3  # some pixels composited to (near) opacity 1


@pytest.mark.parametrize("name", ["dense", "normal"])
def test_cpu_float64_matches_reference_under_gsplats_rules(name):
    """The C++ backend with gsplat's compositing rules (clamp 0.999, stop at T <= 1e-4; the gsplat
    stand-in's) against the torch reference with the same rules, values and gradients, opacities up
    to 1 (the clamp active)."""
    leaves, bins, _ = projected_inputs(name)
    leaves[2] = 1.0 - 0.1 * (1.0 - leaves[2])
    ref = values_and_grads(functools.partial(rasterize_torch, rules=GSPLAT), leaves, bins)
    got = values_and_grads(functools.partial(rasterize_cpu, rules=GSPLAT), leaves, bins)
    for label, r, c in zip(
        ["colour", "T", "means2d", "conics", "opacities", "features"], ref, got, strict=True
    ):
        torch.testing.assert_close(
            c, r, rtol=1e-9, atol=1e-11, msg=lambda m, label=label: f"{name}/{label}: {m}"
        )
    three_dgs = values_and_grads(rasterize_cpu, leaves, bins)
    if name == "dense":  # the rules matter: 3DGS's give other transmittances
        assert float((got[1] - three_dgs[1]).abs().max()) > 1e-4


@pytest.mark.parametrize("name", sorted(SCENES))
def test_cpu_float32_matches_float64_reference(name):
    """float32 kernel vs float64 reference: relative 1e-5 of each tensor's scale
    (plus 1e-5 elementwise)."""
    leaves, bins, _ = projected_inputs(name)
    ref = values_and_grads(rasterize_torch, leaves, bins)
    got = values_and_grads(rasterize_cpu, [t.float() for t in leaves], bins)
    for label, r, c in zip(
        ["colour", "T", "means2d", "conics", "opacities", "features"], ref, got, strict=True
    ):
        scale = float(r.abs().max()) or 1.0
        torch.testing.assert_close(
            c.double(),
            r,
            rtol=1e-5,
            atol=1e-5 * scale,
            msg=lambda m, label=label: f"{name}/{label}: {m}",
        )


def test_deterministic_across_thread_counts():
    leaves, bins, _ = projected_inputs("dense", torch.float32)
    leaves[2] = leaves[2] * 0.6  # fewer terminated pixels: longer lists per pixel

    def run(threads):
        return values_and_grads(lambda *a: rasterize_cpu(*a, threads=threads), leaves, bins)

    one, two, three = run(1), run(2), run(3)
    for a, b, c in zip(one, two, three, strict=True):
        assert torch.equal(a, b) and torch.equal(a, c)
    gathers = [shadow_gather_cpu(*leaves[:3], bins, threads=t) for t in (1, 2, 3)]
    for field in ("vis_sum", "count", "weight"):
        assert all(torch.equal(getattr(gathers[0], field), getattr(g, field)) for g in gathers[1:])


def test_rasterize_cpu_and_torch_agree_through_public_api_with_depth():
    W, H = 45, 31
    w2c, K = camera(W, H)
    s = scene(80, channels=12, spread=1.2)
    p = project(s["means"], s["quats"], s["scales"], w2c, K, W, H)
    a = rasterize(
        p, s["opacities"], s["features"], s["background"], backend="torch", return_depth=True
    )
    b = rasterize(
        p, s["opacities"], s["features"], s["background"], backend="cpu", return_depth=True
    )
    assert (a.backend, b.backend) == ("torch", "cpu")
    for x, y in ((a.image, b.image), (a.alpha, b.alpha), (a.depth, b.depth)):
        torch.testing.assert_close(y, x, rtol=1e-10, atol=1e-12)


def shadow_brute_force(means2d, conics, opacities, bins, radius):
    """Per-pixel Python loop implementing the documented light-pass rules."""
    n = means2d.shape[0]
    vis, cnt, wsum = [0.0] * n, [0] * n, [0.0] * n
    m, con, op = means2d.tolist(), conics.tolist(), opacities.tolist()
    for t in range(bins.num_tiles):
        ids = bins.gaussian_ids[bins.offsets[t] : bins.offsets[t + 1]].tolist()
        tx, ty = t % bins.tiles_x, t // bins.tiles_x
        for y in range(ty * 16, min(bins.height, ty * 16 + 16)):
            for x in range(tx * 16, min(bins.width, tx * 16 + 16)):
                T, done = 1.0, False
                for g in ids:
                    dx, dy = m[g][0] - x - 0.5, m[g][1] - y - 0.5
                    if dx * dx + dy * dy <= radius * radius:
                        vis[g] += 0.0 if done else T
                        cnt[g] += 1
                    power = -0.5 * (con[g][0] * dx * dx + con[g][2] * dy * dy) - con[g][1] * dx * dy
                    if done or power > 0:
                        continue
                    alpha = min(0.99, op[g] * math.exp(power))
                    if alpha < 1 / 255:
                        continue
                    if T * (1 - alpha) < 1e-4:
                        done = True
                        continue
                    wsum[g] += T * alpha
                    T *= 1 - alpha
    return (
        torch.tensor(vis, dtype=D),
        torch.tensor(cnt, dtype=torch.int32),
        torch.tensor(wsum, dtype=D),
    )


@pytest.mark.parametrize("name", ["normal", "dense", "offscreen_and_behind"])
def test_shadow_gather_matches_brute_force(name):
    (means2d, conics, opacities, _), depth_bins, radii = projected_inputs(name)
    # Sort by a key other than depth (as the light pass does with squared distance) to exercise
    # sort_keys.
    keys = (means2d - torch.tensor([3.0, 2.0], dtype=D)).square().sum(-1)
    bins = bin_gaussians(means2d, radii, keys, depth_bins.width, depth_bins.height)
    opacities = opacities.clone()
    opacities[::7] = 0.002  # below 1/255: never composited, but still records its visibility
    got = shadow_gather_cpu(means2d, conics, opacities, bins, radius_px=2.0)
    vis, cnt, wsum = shadow_brute_force(means2d, conics, opacities, bins, 2.0)
    assert torch.equal(got.count, cnt)
    torch.testing.assert_close(got.vis_sum, vis, rtol=1e-10, atol=1e-12)
    torch.testing.assert_close(got.weight, wsum, rtol=1e-10, atol=1e-12)
    assert (cnt > 0).sum() >= 3
    got32 = shadow_gather_cpu(
        means2d.float(), conics.float(), opacities.float(), bins, radius_px=2.0
    )
    torch.testing.assert_close(got32.vis_sum.double(), vis, rtol=1e-4, atol=1e-4)


def test_torch_reference_is_chunk_independent(monkeypatch):
    """Many small chunks (and the checkpointed backward) give the same values and gradients as the
    C++ kernel."""
    import olatbench.gaussians.backends.torch_ref as torch_ref

    leaves, bins, _ = projected_inputs("twelve_channels")
    monkeypatch.setattr(torch_ref, "CHUNK_ELEMENTS", 2000)
    assert len(torch_ref._chunks(bins.offsets[1:] - bins.offsets[:-1], 256)) > 3
    chunked = values_and_grads(rasterize_torch, leaves, bins)
    for a, b in zip(chunked, values_and_grads(rasterize_cpu, leaves, bins), strict=True):
        torch.testing.assert_close(a, b, rtol=1e-9, atol=1e-11)


def _binning_inputs(n: int, width: int, height: int, dtype: torch.dtype, seed: int):
    """Means partly off-image (and a few non-finite), radii 0..11, sort keys with ties, negatives,
    -0 and NaN."""
    g = torch.Generator().manual_seed(seed)
    size = torch.tensor([width, height], dtype=torch.float64)
    means = (torch.rand(n, 2, generator=g, dtype=torch.float64) * 1.4 - 0.2) * size
    radii = torch.randint(0, 12, (n,), generator=g)
    keys = torch.randint(0, 5, (n,), generator=g).to(torch.float64) * 0.5 - 1.0
    if n >= 4:
        means[0, 0], means[1, 1], keys[2], keys[3] = float("nan"), float("inf"), float("nan"), -0.0
    return means.to(dtype), radii, keys.to(dtype)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize(
    ("n", "width", "height"), [(0, 8, 8), (1, 8, 8), (300, 37, 23), (5000, 128, 96)]
)
def test_cpp_binning_is_identical_to_torch(dtype, n, width, height):
    means, radii, keys = _binning_inputs(n, width, height, dtype, seed=n)
    ref = bin_gaussians(means, radii, keys, width, height, backend="torch")
    got = bin_gaussians(means, radii, keys, width, height, backend="cpu")
    assert torch.equal(got.offsets, ref.offsets)
    assert torch.equal(got.gaussian_ids, ref.gaussian_ids)
    assert (got.tiles_x, got.tiles_y, got.tile_size) == (ref.tiles_x, ref.tiles_y, ref.tile_size)


def test_cpp_binning_handles_huge_and_fractional_coordinates():
    """Coordinates beyond 2^23 (float32 integers) and just around pixel-centre boundaries."""
    means = torch.tensor(
        [[3e9, 4.0], [-3e9, 4.0], [7.5, 7.5], [8.4999, 0.5], [15.5000, 15.5], [-0.49, 2.0]]
    )
    radii = torch.tensor([5, 5, 1, 1, 1, 1])
    keys = torch.arange(6, dtype=torch.float32)
    for dtype in (torch.float32, torch.float64):
        ref = bin_gaussians(means.to(dtype), radii, keys, 32, 16, backend="torch")
        got = bin_gaussians(means.to(dtype), radii, keys, 32, 16, backend="cpu")
        assert torch.equal(got.offsets, ref.offsets) and torch.equal(
            got.gaussian_ids, ref.gaussian_ids
        )


def _projection_outputs(
    backend: str, dtype: torch.dtype, name: str, quat_scale: float = 1.7, seed: int = 3
):
    """project() values and the gradients of a random linear loss w.r.t. means, quats, scales and
    w2c."""
    cfg = dict(SCENES[name])
    n, (W, H) = cfg.pop("n"), cfg.pop("size")
    cfg.pop("channels", None)
    cfg.pop("opacity", None)
    w2c, K = camera(W, H)
    s = scene(n, **cfg)
    leaves = [
        t.to(dtype).clone().requires_grad_()
        for t in (s["means"], s["quats"] * quat_scale, s["scales"], w2c)
    ]
    p = project(*leaves, K.to(dtype), W, H, backend=backend)
    g = torch.Generator().manual_seed(seed)
    outputs = (p.means2d, p.conics, p.depths)
    loss = sum((t * torch.randn(t.shape, generator=g, dtype=D).to(dtype)).sum() for t in outputs)
    loss.backward()
    return {
        "means2d": p.means2d.detach(),
        "conics": p.conics.detach(),
        "radii": p.radii,
        "depths": p.depths.detach(),
        **{
            f"grad_{k}": t.grad
            for k, t in zip(("means", "quats", "scales", "w2c"), leaves, strict=True)
        },
    }


@pytest.mark.parametrize("name", ["normal", "dense", "offscreen_and_behind", "degenerate_scales"])
def test_cpp_projection_matches_torch_in_float64(name):
    """Values, radii and every gradient (unnormalised quaternions, culled and off-screen Gaussians
    included)."""
    ref = _projection_outputs("torch", D, name)
    got = _projection_outputs("cpu", D, name)
    assert torch.equal(got["radii"], ref["radii"])
    for key in ref:
        torch.testing.assert_close(
            got[key], ref[key], rtol=1e-9, atol=1e-12, msg=lambda m, key=key: f"{key}: {m}"
        )


def test_cpp_projection_matches_torch_in_float32():
    ref = _projection_outputs("torch", torch.float32, "dense")
    got = _projection_outputs("cpu", torch.float32, "dense")
    # a ceil within float32 rounding of an integer
    assert (got["radii"] - ref["radii"]).abs().max() <= 1
    assert (got["radii"] != ref["radii"]).float().mean() < 0.02
    for key in (
        "means2d",
        "conics",
        "depths",
        "grad_means",
        "grad_quats",
        "grad_scales",
        "grad_w2c",
    ):
        scale = ref[key].abs().max()
        torch.testing.assert_close(
            got[key],
            ref[key],
            rtol=1e-4,
            atol=1e-5 * float(scale),
            msg=lambda m, key=key: f"{key}: {m}",
        )


def test_projection_auto_backend_choice():
    """auto = C++ on CPU tensors; a K that needs a gradient (unsupported in C++) takes the torch
    path."""
    W, H = 37, 23
    w2c, K = camera(W, H)
    s = scene(20)
    auto = project(s["means"], s["quats"], s["scales"], w2c, K, W, H)
    cpp = project(s["means"], s["quats"], s["scales"], w2c, K, W, H, backend="cpu")
    assert torch.equal(auto.means2d, cpp.means2d) and torch.equal(auto.conics, cpp.conics)
    K_grad = K.clone().requires_grad_()
    p = project(s["means"], s["quats"], s["scales"], w2c, K_grad, W, H)
    p.means2d.sum().backward()
    assert K_grad.grad is not None
    with pytest.raises(ValueError, match="projection backend"):
        project(s["means"], s["quats"], s["scales"], w2c, K, W, H, backend="gpu")
