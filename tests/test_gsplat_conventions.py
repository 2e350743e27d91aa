"""The CUDA backend's conventions checked against gsplat's own code, on CPU tensors (no GPU needed).

The CUDA path feeds gsplat's ``rasterize_to_pixels`` with olatbench's projection and tile bins. Here
gsplat's torch twin of that kernel (made CPU-runnable by `gsplat_cpu`) stands in for the CUDA one
inside ``backends.cuda.rasterize_cuda``, and olatbench's projection and binning are compared with
gsplat's ``_fully_fused_projection``, ``_isect_tiles`` and ``_isect_offset_encode``. A wrong pixel
centre, tile layout, conic or transmittance convention in olatbench (or a changed one in a new
gsplat) fails these tests.
"""

from __future__ import annotations

import functools
import math

import pytest
import torch
from gsplat_cpu import ALPHA_CLAMP, cpu_gsplat, gsplat_torch
from test_rasterize_scenes import camera, scene

from olatbench.gaussians.backends import cuda as cuda_backend
from olatbench.gaussians.backends import torch_ref
from olatbench.gaussians.compositing import GSPLAT
from olatbench.gaussians.projection import project
from olatbench.gaussians.tiles import TILE_SIZE, bin_gaussians

W, H = 45, 37  # not multiples of 16: the last tile row and column are partial


def projected_scene(
    n: int = 120, seed: int = 0, dtype: torch.dtype = torch.float64, **scene_options
):
    """(scene dict, Projected, TileBins) of random Gaussians in front of the test camera, covering
    every tile."""
    s = scene(n, seed=seed, dtype=dtype, **{"spread": 1.5, "scale": (0.05, 0.25), **scene_options})
    w2c, K = camera(W, H, dtype=dtype)
    projected = project(s["means"], s["quats"], s["scales"], w2c, K, W, H, backend="torch")
    bins = bin_gaussians(
        projected.means2d, projected.radii, projected.depths, W, H, backend="torch"
    )
    return s, projected, bins


@pytest.fixture
def gsplat_on_cpu(monkeypatch):
    cpu_gsplat(monkeypatch)


@pytest.fixture
def gsplat_clamp(monkeypatch):
    """olatbench's torch reference with gsplat's rules (clamp 0.999 instead of 3DGS's 0.99, stop at
    T <= 1e-4)."""
    monkeypatch.setattr(
        torch_ref, "rasterize_torch", functools.partial(torch_ref.rasterize_torch, rules=GSPLAT)
    )


def test_the_documented_gsplat_clamp_is_the_one_in_gsplat():
    assert cuda_backend.GSPLAT_ALPHA_MAX == ALPHA_CLAMP
    assert torch_ref.ALPHA_MAX == 0.99


@pytest.mark.parametrize(
    "opacity", [(0.2, 0.85), (0.9, 1.0)], ids=["clamp-inactive", "clamp-active"]
)
def test_wrapper_with_gsplat_torch_kernel_matches_the_torch_reference(
    gsplat_on_cpu, gsplat_clamp, opacity
):
    """Colours and transmittance agree to float64 rounding once both clamp alpha at 0.999."""
    s, projected, bins = projected_scene(opacity=opacity)
    assert bins.num_pairs > 300 and bool((bins.offsets[1:] > bins.offsets[:-1]).all())
    args = (projected.means2d, projected.conics, s["opacities"], s["features"], bins)
    colour, trans = cuda_backend.rasterize_cuda(*args)
    colour_ref, trans_ref = torch_ref.rasterize_torch(*args)
    assert colour.shape == (H, W, 3) and trans.shape == (H, W)
    assert float((1 - trans_ref).max()) > 0.9  # dense enough that the 1e-4 stop and overlaps matter
    torch.testing.assert_close(colour, colour_ref, rtol=0, atol=1e-10)
    torch.testing.assert_close(trans, trans_ref, rtol=0, atol=1e-10)


def test_alpha_clamp_difference_is_exactly_the_two_clamps(gsplat_on_cpu):
    """Opaque Gaussian centred on a pixel: gsplat leaves T = 1 - 0.999, olatbench's 3DGS clamp T = 1
    - 0.99."""
    means2d = torch.tensor([[8.5, 5.5]], dtype=torch.float64)  # the centre of pixel (8, 5)
    conics = torch.tensor([[0.5, 0.0, 0.5]], dtype=torch.float64)
    opacities = torch.ones(1, dtype=torch.float64)
    features = torch.ones(1, 1, dtype=torch.float64)
    radii = torch.tensor([4])
    bins = bin_gaussians(
        means2d, radii, torch.ones(1, dtype=torch.float64), 16, 16, backend="torch"
    )
    _, trans = cuda_backend.rasterize_cuda(means2d, conics, opacities, features, bins)
    _, trans_ref = torch_ref.rasterize_torch(means2d, conics, opacities, features, bins)
    assert float(trans[5, 8]) == pytest.approx(1 - cuda_backend.GSPLAT_ALPHA_MAX, abs=1e-12)
    assert float(trans_ref[5, 8]) == pytest.approx(1 - torch_ref.ALPHA_MAX, abs=1e-12)
    away = trans_ref > 0.02  # where the clamp is inactive the two agree
    torch.testing.assert_close(trans[away], trans_ref[away], rtol=0, atol=1e-12)


def test_gradients_through_the_wrapper_match_the_torch_reference(gsplat_on_cpu, gsplat_clamp):
    s, projected, bins = projected_scene(n=40, seed=3)
    inputs = [
        t.detach().clone().requires_grad_(True)
        for t in (projected.means2d, projected.conics, s["opacities"], s["features"])
    ]
    g = torch.Generator().manual_seed(1)
    colour_weight = torch.rand(H, W, 3, generator=g, dtype=torch.float64)
    trans_weight = torch.rand(H, W, generator=g, dtype=torch.float64)

    def grads(rasterizer):
        colour, trans = rasterizer(*inputs, bins)
        loss = (colour * colour_weight).sum() + (trans * trans_weight).sum()
        return torch.autograd.grad(loss, inputs)

    for name, got, want in zip(
        ("means2d", "conics", "opacities", "features"),
        grads(cuda_backend.rasterize_cuda),
        grads(torch_ref.rasterize_torch),
        strict=True,
    ):
        assert float(want.abs().max()) > 1e-3, name
        torch.testing.assert_close(
            got, want, rtol=1e-9, atol=1e-11, msg=lambda m, n=name: f"{n}: {m}"
        )


def test_wrapper_float32_agrees_with_float64_reference(gsplat_on_cpu, gsplat_clamp):
    """The dtype CUDA training uses: float32 through the wrapper vs the float64 reference."""
    s, projected, bins = projected_scene(dtype=torch.float64)
    colour_ref, trans_ref = torch_ref.rasterize_torch(
        projected.means2d, projected.conics, s["opacities"], s["features"], bins
    )
    colour, trans = cuda_backend.rasterize_cuda(
        projected.means2d.float(),
        projected.conics.float(),
        s["opacities"].float(),
        s["features"].float(),
        bins,
    )
    assert colour.dtype == torch.float32
    torch.testing.assert_close(colour.double(), colour_ref, rtol=0, atol=2e-5)
    torch.testing.assert_close(trans.double(), trans_ref, rtol=0, atol=2e-5)


# --------------------------------------------------------------------------------------------- tile
# bins
def olatbench_footprint_is_gsplats(means2d: torch.Tensor, radius: torch.Tensor) -> torch.Tensor:
    """(N,) bool: the two footprint rules select the same tiles.

    gsplat (``_isect_tiles``) takes tiles [floor((m - r)/16), ceil((m + r)/16)) per axis; olatbench
    the tiles of the pixels whose centres lie in [m - r, m + r]. They differ only when a box edge
    lies within half a pixel outside a tile boundary or the image's last pixel centre, where
    gsplat's conservative rule adds a tile."""
    lo_edge = means2d - radius[:, None]
    hi_edge = means2d + radius[:, None]
    frac_lo = torch.remainder(lo_edge, TILE_SIZE)
    frac_hi = torch.remainder(hi_edge, TILE_SIZE)
    size = torch.tensor([W, H], dtype=means2d.dtype)
    return (
        (frac_lo <= TILE_SIZE - 0.5) & ((frac_hi > 0.5) | (frac_hi == 0)) & (lo_edge <= size - 0.5)
    ).all(-1)


def gsplat_bins(projected, tiles_x: int, tiles_y: int) -> tuple[torch.Tensor, torch.Tensor]:
    """gsplat's (isect_offsets (1, th, tw), flatten_ids) for olatbench's projected Gaussians and
    radii."""
    radii = torch.stack([projected.radii, projected.radii], dim=-1).to(torch.int32)
    _, isect_ids, flatten_ids = gsplat_torch._isect_tiles(
        projected.means2d.detach().float()[None],
        radii[None],
        projected.depths.detach().float()[None],
        TILE_SIZE,
        tiles_x,
        tiles_y,
    )
    offsets = gsplat_torch._isect_offset_encode(isect_ids, 1, tiles_x, tiles_y)
    return offsets, flatten_ids


def test_tile_bins_have_gsplats_layout():
    """Same tile order (row-major), offsets (tile starts, shape (th, tw)) and per-tile depth order
    as gsplat."""
    _, projected, bins = projected_scene(n=50, seed=5)
    same = olatbench_footprint_is_gsplats(
        projected.means2d.detach(), projected.radii.to(torch.float64)
    )
    keep = same & (projected.radii > 0)
    assert int(keep.sum()) >= 25
    radii = torch.where(keep, projected.radii, torch.zeros_like(projected.radii))
    projected.radii = radii
    ours = bin_gaussians(projected.means2d, radii, projected.depths, W, H, backend="torch")
    offsets, flatten_ids = gsplat_bins(projected, ours.tiles_x, ours.tiles_y)
    assert offsets.shape == (1, ours.tiles_y, ours.tiles_x)
    assert torch.equal(
        ours.offsets[:-1].reshape(1, ours.tiles_y, ours.tiles_x), offsets.to(torch.int64)
    )
    assert torch.equal(ours.gaussian_ids, flatten_ids.to(torch.int64))
    assert bins.num_pairs >= ours.num_pairs


def test_gsplat_footprint_contains_olatbenchs_and_keeps_its_order():
    """For every Gaussian, gsplat's tiles ⊇ olatbench's (at most one more per side), depth order
    equal."""
    _, projected, bins = projected_scene(n=80, seed=6)
    offsets, flatten_ids = gsplat_bins(projected, bins.tiles_x, bins.tiles_y)
    starts = offsets.reshape(-1).to(torch.int64)
    ends = torch.cat([starts[1:], torch.tensor([flatten_ids.numel()])])
    extra = 0
    for tile in range(bins.num_tiles):
        ours = bins.gaussian_ids[bins.offsets[tile] : bins.offsets[tile + 1]].tolist()
        theirs = flatten_ids[starts[tile] : ends[tile]].tolist()
        assert set(ours) <= set(theirs), tile
        assert [g for g in theirs if g in set(ours)] == ours, tile  # same front-to-back order
        extra += len(theirs) - len(ours)
    # the rules do differ on this scene (the exact-layout test filters those Gaussians)
    assert extra > 0


# --------------------------------------------------------------------------------------------
# projection
def gsplat_projection(
    s: dict, w2c: torch.Tensor, K: torch.Tensor, width: int, height: int, near: float = 0.01
):
    covars, _ = gsplat_torch._quat_scale_to_covar_preci(
        s["quats"], s["scales"], compute_preci=False
    )
    radii, means2d, depths, conics, _ = gsplat_torch._fully_fused_projection(
        s["means"], covars, w2c[None], K[None], width, height, eps2d=0.3, near_plane=near
    )
    return radii[0], means2d[0], depths[0], conics[0]


def test_projection_matches_gsplat():
    """means2d (no half-pixel shift: K has centres at +0.5 in both), conics (0.3 px low-pass, 1.3×
    frustum clamp), camera-space depths and the culled set; wxyz quaternions in both."""
    # many Gaussians beyond the image edge: exercises the frustum clamp
    s = scene(200, seed=2, spread=1.6)
    w2c, K = camera(W, H)
    ours = project(s["means"], s["quats"], s["scales"], w2c, K, W, H, backend="torch")
    radii, means2d, depths, conics = gsplat_projection(s, w2c, K, W, H)
    torch.testing.assert_close(ours.means2d, means2d, rtol=0, atol=1e-10)
    torch.testing.assert_close(ours.depths, depths, rtol=0, atol=1e-12)
    torch.testing.assert_close(ours.conics, conics, rtol=1e-10, atol=1e-12)
    # Radii: gsplat ceil(3.33·sqrt(Σ_xx)), ceil(3.33·sqrt(Σ_yy)) per axis; olatbench
    # ceil(3·sqrt(λ_max)), the 3DGS rule. Only binning reads radii and the CUDA path bins with
    # olatbench's, so only culling must agree.
    gs_visible = (radii > 0).all(-1)
    inside = (
        (means2d[:, 0] > 8)
        & (means2d[:, 0] < W - 8)
        & (means2d[:, 1] > 8)
        & (means2d[:, 1] < H - 8)
    )
    assert bool(inside.any()) and bool((~inside).any())
    assert torch.equal(ours.visible[inside], gs_visible[inside])


def test_near_and_far_planes_cull_as_gsplat():
    """Both keep Gaussians with near < z < far (strict) in camera space."""
    near, eps = 0.5, 1e-9
    depths = torch.tensor(
        [near - eps, near + eps, 1.0, 50.0 - eps, 50.0 + eps], dtype=torch.float64
    )
    n = depths.numel()
    s = {
        "means": torch.stack(
            [torch.zeros(n, dtype=torch.float64), torch.zeros(n, dtype=torch.float64), depths], -1
        ),
        "quats": torch.tensor([[1.0, 0.0, 0.0, 0.0]], dtype=torch.float64).repeat(n, 1),
        "scales": torch.full((n, 3), 0.01, dtype=torch.float64),
    }
    w2c = torch.eye(4, dtype=torch.float64)
    _, K = camera(W, H)
    ours = project(
        s["means"], s["quats"], s["scales"], w2c, K, W, H, near=near, far=50.0, backend="torch"
    )
    radii, *_ = gsplat_torch._fully_fused_projection(
        s["means"],
        gsplat_torch._quat_scale_to_covar_preci(s["quats"], s["scales"], compute_preci=False)[0],
        w2c[None],
        K[None],
        W,
        H,
        near_plane=near,
        far_plane=50.0,
    )
    assert ours.visible.tolist() == [False, True, True, True, False]
    assert (radii[0] > 0).all(-1).tolist() == ours.visible.tolist()


def test_pixel_centres_are_at_half_integers_in_both():
    """A Gaussian projected onto the principal point cx = W/2 lands between pixels W/2 - 1 and W/2
    (even W)."""
    width = height = 16
    K = torch.tensor([[20.0, 0, 8.0], [0, 20.0, 8.0], [0, 0, 1]], dtype=torch.float64)
    s = {
        "means": torch.tensor([[0.0, 0.0, 2.0]], dtype=torch.float64),
        "quats": torch.tensor([[1.0, 0.0, 0.0, 0.0]], dtype=torch.float64),
        "scales": torch.full((1, 3), 0.05, dtype=torch.float64),
    }
    projected = project(
        s["means"],
        s["quats"],
        s["scales"],
        torch.eye(4, dtype=torch.float64),
        K,
        width,
        height,
        backend="torch",
    )
    _, means2d, _, _ = gsplat_projection(s, torch.eye(4, dtype=torch.float64), K, width, height)
    assert projected.means2d.tolist() == means2d.tolist() == [[8.0, 8.0]]
    bins = bin_gaussians(
        projected.means2d, projected.radii, projected.depths, width, height, backend="torch"
    )
    _, trans = torch_ref.rasterize_torch(
        projected.means2d,
        projected.conics,
        torch.full((1,), 0.9, dtype=torch.float64),
        torch.ones(1, 1, dtype=torch.float64),
        bins,
    )
    block = trans[6:10, 6:10]
    # symmetric about (8, 8)
    torch.testing.assert_close(block, block.flip(0).flip(1), rtol=0, atol=1e-15)
    assert math.isclose(float(trans[7, 7]), float(trans[8, 8]), abs_tol=1e-15)
