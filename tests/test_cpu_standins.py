"""The CPU stand-ins of the authors' CUDA-only modules (olatbench.methods.official.cpu_standins),
each against an independent reference: the light splat against a brute-force, pixel-by-pixel reading
of forward.cu; gsplat's ``rasterization`` against gsplat's own torch implementation; the tinycudann
encoding and network against their closed forms; distCUDA2 against brute-force nearest neighbours;
the device shim and the job environment in a fresh interpreter."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from olatbench.methods.official.cpu_standins import SITE, job_environment
from olatbench.methods.official.cpu_standins.knn import distCUDA2
from olatbench.methods.official.cpu_standins.light import (
    VARIANTS,
    GaussianRasterizationSettings,
    GaussianRasterizer,
    light_splat,
)
from olatbench.methods.official.cpu_standins.save_image import save_image
from olatbench.methods.official.cpu_standins.tcnn import Encoding, Network

F32 = np.float32


# ------------------------------------------------------------------------------------------------
# light splat
def light_settings(width: int = 40, height: int = 30, tanfov: float = 0.3, eye=(0.4, -0.5, 3.0)):
    """3DGS-layout view and full projection matrices of a camera at ``eye`` looking at the origin
    (OpenCV axes), as the authors build them (getProjectionMatrix, then viewmatrix @ projection)."""
    eye = np.asarray(eye, np.float64)
    forward = -eye / np.linalg.norm(eye)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    w2c = np.eye(4)
    w2c[:3, :3] = np.stack([right, down, forward])
    w2c[:3, 3] = -w2c[:3, :3] @ eye
    near, far = 0.01, 100.0
    tany = tanfov * height / width
    proj = np.zeros((4, 4))
    proj[0, 0], proj[1, 1] = 1 / tanfov, 1 / tany
    proj[3, 2], proj[2, 2], proj[2, 3] = 1.0, far / (far - near), -(far * near) / (far - near)
    view = torch.tensor(w2c.T, dtype=torch.float32)
    full = torch.tensor(w2c.T @ proj.T, dtype=torch.float32)
    return GaussianRasterizationSettings(
        height,
        width,
        tanfov,
        tany,
        torch.zeros(3),
        1.0,
        view,
        full,
        0,
        torch.tensor(eye, dtype=torch.float32),
        False,
        False,
    )


def light_scene(n: int = 40, seed: int = 0, spread: float = 0.6):
    g = torch.Generator().manual_seed(seed)
    means = (torch.rand(n, 3, generator=g) * 2 - 1) * spread
    scales = 0.03 + torch.rand(n, 3, generator=g) * 0.12
    rotations = torch.nn.functional.normalize(torch.randn(n, 4, generator=g), dim=1)
    opacities = 0.3 + 0.7 * torch.rand(n, 1, generator=g)
    return means, scales, rotations, opacities


def cov3d_of(scale, quat):
    r, x, y, z = (float(v) for v in quat)
    rot = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - r * z), 2 * (x * z + r * y)],
            [2 * (x * y + r * z), 1 - 2 * (x * x + z * z), 2 * (y * z - r * x)],
            [2 * (x * z - r * y), 2 * (y * z + r * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    m = rot @ np.diag(np.asarray(scale, np.float64))
    sigma = m @ m.T
    return [sigma[0, 0], sigma[0, 1], sigma[0, 2], sigma[1, 1], sigma[1, 2], sigma[2, 2]]


def brute_force_light(means, opacities, cov3d, settings, offset, thres, is_train, clip):
    """forward.cu read line by line, one Gaussian and one pixel at a time, in float32
    (the reference)."""
    width, height = settings.image_width, settings.image_height
    vm = settings.viewmatrix.numpy().reshape(-1).astype(F32)  # 3DGS layout: vm[4*r + c]
    pm = settings.projmatrix.numpy().reshape(-1).astype(F32)
    tanx, tany = F32(settings.tanfovx), F32(settings.tanfovy)
    fx, fy = F32(width / (2 * settings.tanfovx)), F32(height / (2 * settings.tanfovy))
    grid = ((width + 15) // 16, (height + 15) // 16)
    n = len(means)
    radii = [0] * n
    data = {}
    for i in range(n):
        p = [F32(v) for v in means[i]]
        ph = [pm[c] * p[0] + pm[4 + c] * p[1] + pm[8 + c] * p[2] + pm[12 + c] for c in range(4)]
        pw = F32(1) / (ph[3] + F32(1e-7))
        proj = [ph[c] * pw for c in range(3)]
        t = [vm[c] * p[0] + vm[4 + c] * p[1] + vm[8 + c] * p[2] + vm[12 + c] for c in range(3)]
        if t[2] <= 0.2:
            continue
        limx, limy = F32(1.3) * tanx, F32(1.3) * tany
        tx = min(limx, max(-limx, t[0] / t[2])) * t[2]
        ty = min(limy, max(-limy, t[1] / t[2])) * t[2]
        tz = t[2]
        # glm::mat3(a0, ..., a8) takes columns: numpy rows below are glm columns, hence the
        # transposes
        J = np.array(
            [[fx / tz, 0, -(fx * tx) / (tz * tz)], [0, fy / tz, -(fy * ty) / (tz * tz)], [0, 0, 0]],
            F32,
        ).T
        Wm = np.array([[vm[0], vm[4], vm[8]], [vm[1], vm[5], vm[9]], [vm[2], vm[6], vm[10]]], F32).T
        c = cov3d[i]
        vrk = np.array([[c[0], c[1], c[2]], [c[1], c[3], c[4]], [c[2], c[4], c[5]]], F32)
        T = Wm @ J
        cov = T.T @ vrk.T @ T
        a, b, cc = F32(cov[0, 0] + F32(0.3)), F32(cov[0, 1]), F32(cov[1, 1] + F32(0.3))
        det = a * cc - b * b
        if det == 0:
            continue
        mid = F32(0.5) * (a + cc)
        lam1 = mid + math.sqrt(max(0.1, mid * mid - det))
        lam2 = mid - math.sqrt(max(0.1, mid * mid - det))
        radius = math.ceil(3 * math.sqrt(max(lam1, lam2)))
        px = ((proj[0] + F32(1)) * width - F32(1)) * F32(0.5)
        py = ((proj[1] + F32(1)) * height - F32(1)) * F32(0.5)
        rmin = (
            min(grid[0], max(0, int((px - radius) / 16))),
            min(grid[1], max(0, int((py - radius) / 16))),
        )
        rmax = (
            min(grid[0], max(0, int((px + radius + 15) / 16))),
            min(grid[1], max(0, int((py + radius + 15) / 16))),
        )
        if (rmax[0] - rmin[0]) * (rmax[1] - rmin[1]) == 0:
            continue
        radii[i] = radius
        data[i] = dict(
            xy=(F32(px), F32(py)),
            conic=(cc / det, -b / det, a / det),
            o=F32(opacities[i]),
            depth=F32(t[2] * t[2] + t[1] * t[1] + t[0] * t[0]),
            rect=(rmin, rmax),
        )
    trans, non_trans, weight = np.zeros(n), np.zeros(n), np.zeros(n)

    def power(g, x, y):
        d = data[g]
        dx, dy = d["xy"][0] - F32(x), d["xy"][1] - F32(y)
        con = d["conic"]
        return F32(-0.5) * (con[0] * dx * dx + con[2] * dy * dy) - con[
            1
        ] * dx * dy, dx * dx + dy * dy

    for y in range(height):
        for x in range(width):
            tile = (x // 16, y // 16)
            members = [
                g
                for g, d in data.items()
                if d["rect"][0][0] <= tile[0] < d["rect"][1][0]
                and d["rect"][0][1] <= tile[1] < d["rect"][1][1]
            ]
            members.sort(key=lambda g: (data[g]["depth"], g))
            T, w, depth_t, pointer = F32(1), F32(1), F32(0), 0
            for j in members:
                pj, dd = power(j, x, y)
                if clip is not None:
                    pj = min(pj, F32(clip))
                dj = data[j]["depth"]

                def record(value, pj=pj, dd=dd, j=j):
                    if dd < thres:
                        trans[j] += math.exp(pj) * value
                        non_trans[j] += math.exp(pj)

                if dj - depth_t > offset:
                    while True:
                        p = members[pointer]
                        pointer += 1
                        pp, _ = power(p, x, y)
                        depth_t = data[p]["depth"]
                        alpha = F32(0)
                        if pp <= 0:
                            alpha = min(F32(0.99), data[p]["o"] * F32(math.exp(pp)))
                            alpha = F32(0) if alpha < 1 / 255 else alpha
                        w = alpha * T
                        if dj - depth_t <= offset:
                            record(T)
                            T = T * (F32(1) - alpha)
                            break
                        T = T * (F32(1) - alpha)
                else:
                    record(T)
                if is_train:
                    weight[j] += w
    return np.array(radii), trans, non_trans, weight


@pytest.mark.parametrize(
    ("offset", "thres", "seed"),
    [(0.015, 4.0, 0), (0.3, 9.0, 1), (0.0, 4.0, 2)],
    ids=["official-offset", "wide-band", "no-offset"],
)
def test_light_splat_matches_brute_force_forward_cu(offset, thres, seed):
    means, scales, rotations, opacities = light_scene(seed=seed)
    settings = light_settings()
    cov3d = [cov3d_of(s, q) for s, q in zip(scales.numpy(), rotations.numpy(), strict=False)]
    radii_ref, trans_ref, non_ref, weight_ref = brute_force_light(
        means.numpy(), opacities.numpy()[:, 0], cov3d, settings, offset, thres, True, None
    )
    non_trans = torch.zeros(len(means))
    out_weight, radii, trans = light_splat(
        means, opacities, scales, rotations, None, settings, non_trans, offset, thres, True, None
    )
    assert radii.dtype == torch.int32 and out_weight.shape == (len(means), 1)
    assert radii.tolist() == radii_ref.tolist()
    # shadows occur
    assert (radii > 0).sum() > 30 and trans_ref.max() > 0 and (trans_ref < non_ref - 1e-3).any()
    np.testing.assert_allclose(non_trans.numpy(), non_ref, rtol=2e-4, atol=1e-5)
    np.testing.assert_allclose(trans.numpy(), trans_ref, rtol=2e-4, atol=1e-5)
    np.testing.assert_allclose(out_weight[:, 0].numpy(), weight_ref, rtol=2e-4, atol=1e-4)


def test_light_variants_differ_only_by_the_ssdgs_power_clamp():
    """With a non-positive-definite precomputed covariance power_j can exceed 10: SSD-GS clamps it,
    GS³ not."""
    means, scales, rotations, opacities = light_scene(n=12, seed=3)
    settings = light_settings()
    cov3d = [cov3d_of(s, q) for s, q in zip(scales.numpy(), rotations.numpy(), strict=False)]
    # Gaussian 0: in light-view axes variance -1e-3 along x (≈ -0.37 px² on screen, -0.07 after the
    # +0.3 low-pass), so its conic is strongly negative along x and power_j > 10 within 2 px of its
    # centre
    m = settings.viewmatrix.numpy()[:3, :3].astype(np.float64)  # world -> view is m.T
    sigma = m @ np.diag([-1e-3, 2e-3, 1e-3]) @ m.T
    cov3d[0] = [sigma[0, 0], sigma[0, 1], sigma[0, 2], sigma[1, 1], sigma[1, 2], sigma[2, 2]]
    cov = torch.tensor(cov3d, dtype=torch.float32)
    results = {}
    for variant, clip in VARIANTS.items():
        non_trans = torch.zeros(len(means))
        _, _radii, trans = light_splat(
            means, opacities, None, None, cov, settings, non_trans, 0.015, 4.0, False, clip
        )
        reference = brute_force_light(
            means.numpy(), opacities.numpy()[:, 0], cov3d, settings, 0.015, 4.0, False, clip
        )
        np.testing.assert_allclose(trans.numpy(), reference[1], rtol=2e-4, atol=1e-5)
        np.testing.assert_allclose(non_trans.numpy(), reference[2], rtol=2e-4, atol=1e-5)
        results[variant] = non_trans
    assert VARIANTS == {"ssdgs-26e4251": 10.0, "gs3-83c8daa": None}
    clamped, unclamped = float(results["ssdgs-26e4251"][0]), float(results["gs3-83c8daa"][0])
    # ≤ 13 pixels with dd < 4
    assert 0 < clamped <= 13 * math.exp(10) * (1 + 1e-5) and unclamped > 2 * clamped
    torch.testing.assert_close(results["gs3-83c8daa"][1:], results["ssdgs-26e4251"][1:])


def test_light_rasterizer_refuses_gradients_and_an_unknown_variant(monkeypatch):
    means, scales, rotations, opacities = light_scene(n=5)
    monkeypatch.delenv("OLATBENCH_STANDIN_LIGHT", raising=False)
    with pytest.raises(
        ValueError, match=r"OLATBENCH_STANDIN_LIGHT=None names no known forward\.cu"
    ):
        GaussianRasterizer(light_settings())
    monkeypatch.setenv("OLATBENCH_STANDIN_LIGHT", "gs3-83c8daa")
    rasterizer = GaussianRasterizer(light_settings())
    with pytest.raises(NotImplementedError, match="forward only"):
        rasterizer(
            means.requires_grad_(),
            None,
            opacities,
            colors_precomp=torch.zeros(2, 3),
            scales=scales,
            rotations=rotations,
            non_trans=torch.zeros(5),
        )
    with torch.no_grad():
        color, out_weight, radii, trans = rasterizer(
            means,
            None,
            opacities,
            colors_precomp=torch.zeros(2, 3),
            scales=scales,
            rotations=rotations,
            non_trans=torch.zeros(5),
        )
    assert (
        color.shape == (2, 2, 2)
        and out_weight.shape == (5, 1)
        and radii.shape == trans.shape == (5,)
    )
    assert float(out_weight.abs().sum()) == 0.0  # is_train False: no weights


# ---------------------------------------------------------------------------------------------
# rasterization
def test_rasterization_matches_gsplats_torch_implementation(monkeypatch):
    pytest.importorskip("gsplat")
    from gsplat_cpu import cpu_gsplat, gsplat_torch
    from test_rasterize_scenes import camera, scene

    from olatbench.methods.official.cpu_standins.rasterization import rasterization

    cpu_gsplat(monkeypatch)
    width, height, channels = 45, 37, 13  # partial tiles; 13 channels as SSD-GS's colours
    s = scene(150, channels=channels, seed=4, spread=1.2, opacity=(0.2, 0.85))
    w2c, K = camera(width, height)
    background = torch.rand(1, channels, dtype=torch.float64)
    means = s["means"].clone().requires_grad_()
    image, alpha, meta = rasterization(
        means,
        s["quats"],
        s["scales"],
        s["opacities"],
        s["features"],
        w2c[None],
        K[None],
        width,
        height,
        near_plane=0.01,
        far_plane=100.0,
        eps2d=0.3,
        sh_degree=None,
        packed=False,
        backgrounds=background,
    )
    meta["means2d"].retain_grad()
    weights = torch.rand(1, height, width, channels, dtype=torch.float64)
    (image * weights).sum().backward()

    covars, _ = gsplat_torch._quat_scale_to_covar_preci(
        s["quats"], s["scales"], compute_preci=False
    )
    radii, means2d, depths, conics, _ = gsplat_torch._fully_fused_projection(
        s["means"],
        covars,
        w2c[None],
        K[None],
        width,
        height,
        eps2d=0.3,
        near_plane=0.01,
        far_plane=100.0,
    )
    means2d = means2d.detach().requires_grad_()
    tiles_x, tiles_y = (width + 15) // 16, (height + 15) // 16
    # gsplat 1.5 has per-axis radii: bin with the stand-in's (1.1.1-style) radii so both composite
    # the same lists
    _, isect_ids, flatten_ids = gsplat_torch._isect_tiles(
        means2d.detach(), meta["radii"][..., None].expand(-1, -1, 2), depths, 16, tiles_x, tiles_y
    )
    offsets = gsplat_torch._isect_offset_encode(isect_ids, 1, tiles_x, tiles_y)
    ref_image, ref_alpha = gsplat_torch._rasterize_to_pixels(
        means2d,
        conics,
        s["features"][None],
        s["opacities"][None],
        width,
        height,
        16,
        offsets,
        flatten_ids,
        backgrounds=background,
    )
    (ref_image * weights).sum().backward()

    assert image.shape == (1, height, width, channels) and alpha.shape == (1, height, width, 1)
    assert meta["radii"].shape == (1, 150) and meta["radii"].dtype == torch.int32
    assert meta["means2d"].shape == (1, 150, 2)
    assert torch.equal(meta["radii"][0] > 0, (radii[0] > 0).all(-1))
    torch.testing.assert_close(meta["means2d"].detach(), means2d.detach(), rtol=0, atol=1e-10)
    torch.testing.assert_close(image, ref_image, rtol=0, atol=1e-9)
    torch.testing.assert_close(alpha, ref_alpha, rtol=0, atol=1e-9)
    visible = meta["radii"][0] > 0
    assert float(means2d.grad.abs().sum()) > 0
    torch.testing.assert_close(
        meta["means2d"].grad[0][visible], means2d.grad[0][visible], rtol=1e-6, atol=1e-9
    )


def gsplat_111_projection(
    means, quats, scales, viewmat, K, width, height, eps2d=0.3, near=0.01, far=100.0
):
    """gsplat v1.1.1's projection, transcribed from its CUDA (not from olatbench):
    ``fully_fused_projection_fwd.cu`` :59 (cull z < near or z > far), :86-102 (``persp_proj``,
    ``add_blur``, det <= 0 culled, the radius with ``max(0.01, b² - det)``), :112-113
    (off-image boxes); ``utils.cuh:152-170`` (``persp_proj``: x/z, y/z clamped to ±1.3·W/(2fx),
    ±1.3·H/(2fy)). (The installed gsplat 1.5's torch code clamps at the image edges and has per-axis
    radii; 1.1.1's torch code, ``_torch_impl.py:86-92, 179-185``, has this clamp and floor but culls
    z == near, unlike its CUDA.) Returns radii (N,) int, means2d (N, 2), conics (N, 3), all
    float64."""
    from gsplat_cpu import gsplat_torch

    covars, _ = gsplat_torch._quat_scale_to_covar_preci(quats, scales, compute_preci=False)
    R, t = viewmat[:3, :3], viewmat[:3, 3]
    mean_c = means @ R.T + t
    cov_c = R @ covars @ R.T
    x, y, z = mean_c.unbind(-1)
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    lim_x, lim_y = 1.3 * 0.5 * width / fx, 1.3 * 0.5 * height / fy
    rz = 1.0 / z
    tx = z * torch.minimum(lim_x, torch.maximum(-lim_x, x * rz))
    ty = z * torch.minimum(lim_y, torch.maximum(-lim_y, y * rz))
    zero = torch.zeros_like(z)
    J = torch.stack(
        [fx * rz, zero, -fx * tx * rz * rz, zero, fy * rz, -fy * ty * rz * rz], -1
    ).reshape(-1, 2, 3)
    cov2d = J @ cov_c @ J.transpose(-1, -2) + eps2d * torch.eye(2, dtype=means.dtype)
    a, b, c = cov2d[:, 0, 0], cov2d[:, 0, 1], cov2d[:, 1, 1]
    det = a * c - b * b
    conics = torch.stack([c / det, -b / det, a / det], -1)
    half = 0.5 * (a + c)
    radius = torch.ceil(
        3.0 * torch.sqrt(half + torch.sqrt(torch.clamp(half * half - det, min=0.01)))
    )
    means2d = torch.stack([fx * x * rz + cx, fy * y * rz + cy], -1)
    mx, my = means2d.unbind(-1)
    culled = (
        (z < near)
        | (z > far)
        | (det <= 0)
        | (radius <= 0)
        | (mx + radius <= 0)
        | (mx - radius >= width)
        | (my + radius <= 0)
        | (my - radius >= height)
    )
    return torch.where(culled, 0.0, radius).to(torch.int64), means2d, conics


def off_centre_camera(width: int, height: int, focal: float = 40.0):
    """The test camera of `test_rasterize_scenes` with the principal point at (0.3 W, 0.65 H)."""
    from test_rasterize_scenes import camera

    w2c, K = camera(width, height, focal)
    K[0, 2], K[1, 2] = 0.3 * width, 0.65 * height
    return w2c, K


def standin(
    means, quats, scales, opacities, colors, w2c, K, width, height, background=None, near=0.01
):
    from olatbench.methods.official.cpu_standins.rasterization import rasterization

    return rasterization(
        means,
        quats,
        scales,
        opacities,
        colors,
        w2c[None],
        K[None],
        width,
        height,
        near_plane=near,
        far_plane=100.0,
        eps2d=0.3,
        sh_degree=None,
        packed=False,
        backgrounds=background,
    )


def test_radius_floor_is_gsplats():
    """gsplat 1.1.1: radius = ceil(3 sqrt(b + sqrt(max(0.01, b² - det)))): nearly isotropic
    footprints (b² - det below 0.01, e.g. every Gaussian smaller than a pixel) get a radius up to 1
    px larger than with a floor at 0."""
    pytest.importorskip("gsplat")
    width, height = 48, 40
    g = torch.Generator().manual_seed(2)
    n = 400
    means = torch.cat(
        [
            (torch.rand(n, 2, generator=g, dtype=torch.float64) - 0.5) * 2.0,
            2.5 + torch.rand(n, 1, generator=g, dtype=torch.float64),
        ],
        1,
    )
    scales = (
        (0.005 + 0.03 * torch.rand(n, 1, generator=g, dtype=torch.float64)).expand(-1, 3).clone()
    )
    quats = torch.randn(n, 4, generator=g, dtype=torch.float64)
    w2c, K = off_centre_camera(width, height)
    _, _, meta = standin(
        means,
        quats,
        scales,
        torch.full((n,), 0.5, dtype=torch.float64),
        torch.rand(n, 3, generator=g, dtype=torch.float64),
        w2c,
        K,
        width,
        height,
    )
    radii, _means2d, _conics = gsplat_111_projection(means, quats, scales, w2c, K, width, height)
    assert torch.equal(meta["radii"][0].long(), radii)
    # The inputs show the difference: with the floor at 0 (3DGS, olatbench's own projection) radii
    # come out smaller.
    from olatbench.gaussians.projection import project

    native = project(means, quats, scales, w2c, K, width, height, backend="torch").radii
    assert int((native < radii).sum()) > n // 10


def test_jacobian_clamp_is_symmetric_about_the_optical_axis_with_off_centre_intrinsics():
    """gsplat 1.1.1 clamps x/z to ±1.3·W/(2 fx) whatever cx (olatbench's projection: at the image
    edges plus 0.3 half-widths, the same only for cx = W/2): conics, radii, means2d and their
    gradients as gsplat's."""
    pytest.importorskip("gsplat")
    width, height = 40, 32
    w2c, K = off_centre_camera(width, height, focal=30.0)
    g = torch.Generator().manual_seed(5)
    n = 300
    depth = 2.0 + torch.rand(n, 1, generator=g, dtype=torch.float64)
    # x/z and y/z over ±2× the clamp: many Gaussians lie beyond it on both sides, large enough to
    # reach the image.
    tangent = (
        (torch.rand(n, 2, generator=g, dtype=torch.float64) * 2 - 1)
        * 2.0
        * 1.3
        * 0.5
        * width
        / 30.0
    )
    means = torch.cat([tangent * depth, depth], 1)
    means = (means - w2c[:3, 3]) @ w2c[:3, :3]  # camera to world
    scales = 0.1 + 0.5 * torch.rand(n, 3, generator=g, dtype=torch.float64)
    quats = torch.randn(n, 4, generator=g, dtype=torch.float64)
    means_in = means.clone().requires_grad_()
    _, _, meta = standin(
        means_in,
        quats,
        scales,
        torch.full((n,), 0.5, dtype=torch.float64),
        torch.rand(n, 3, generator=g, dtype=torch.float64),
        w2c,
        K,
        width,
        height,
    )
    means_ref = means.clone().requires_grad_()
    radii, means2d, conics = gsplat_111_projection(means_ref, quats, scales, w2c, K, width, height)
    visible = radii > 0
    outside = ((means2d[:, 0] - K[0, 2]) / K[0, 0]).abs() > 1.3 * 0.5 * width / K[0, 0]
    assert int((visible & outside).sum()) > 20  # visible Gaussians whose Jacobian is clamped
    assert torch.equal(meta["radii"][0].long(), radii)
    torch.testing.assert_close(
        meta["conics"][0][visible], conics[visible].detach(), rtol=1e-12, atol=0
    )
    torch.testing.assert_close(
        meta["means2d"][0][visible], means2d[visible].detach(), rtol=1e-12, atol=1e-12
    )
    weights = torch.rand(int(visible.sum()), 3, generator=g, dtype=torch.float64)
    (meta["conics"][0][visible] * weights).sum().backward()
    (conics[visible] * weights).sum().backward()
    torch.testing.assert_close(means_in.grad, means_ref.grad, rtol=1e-9, atol=1e-12)


def test_a_gaussian_at_the_near_plane_is_kept():
    """gsplat 1.1.1 culls z < near_plane (fully_fused_projection_fwd.cu:59): z == near_plane is
    projected."""
    pytest.importorskip("gsplat")
    w2c, K = (
        torch.eye(4, dtype=torch.float64),
        torch.tensor([[20.0, 0, 8], [0, 20.0, 8], [0, 0, 1]], dtype=torch.float64),
    )
    means = torch.tensor([[0.0, 0.0, 0.5], [0.0, 0.0, 0.4999]], dtype=torch.float64)
    quats = torch.tensor([[1.0, 0, 0, 0]] * 2, dtype=torch.float64)
    scales = torch.full((2, 3), 0.01, dtype=torch.float64)
    _, _, meta = standin(
        means,
        quats,
        scales,
        torch.full((2,), 0.5, dtype=torch.float64),
        torch.ones(2, 3, dtype=torch.float64),
        w2c,
        K,
        16,
        16,
        near=0.5,
    )
    radii, _, _ = gsplat_111_projection(means, quats, scales, w2c, K, 16, 16, near=0.5)
    assert radii.tolist()[1] == 0 and radii.tolist()[0] > 0
    assert meta["radii"][0].tolist() == radii.tolist()


@pytest.mark.parametrize(
    "opacity", [(0.2, 0.85), (0.9, 1.0)], ids=["clamp-inactive", "clamp-active"]
)
def test_rasterization_with_off_centre_intrinsics_matches_gsplat(monkeypatch, opacity):
    """Images, alphas and means2d gradients as gsplat's own torch rasterizer gives them from gsplat
    1.1.1's projection, with off-centre intrinsics and nearly opaque Gaussians (where alpha reaches
    the 0.999 clamp)."""
    pytest.importorskip("gsplat")
    from gsplat_cpu import cpu_gsplat, gsplat_torch
    from test_rasterize_scenes import scene

    cpu_gsplat(monkeypatch)
    width, height, channels = 45, 37, 4
    s = scene(200, channels=channels, seed=7, spread=1.6, opacity=opacity)
    w2c, K = off_centre_camera(width, height)
    background = torch.rand(1, channels, dtype=torch.float64)
    means = s["means"].clone().requires_grad_()
    image, alpha, meta = standin(
        means,
        s["quats"],
        s["scales"],
        s["opacities"],
        s["features"],
        w2c,
        K,
        width,
        height,
        background,
    )
    meta["means2d"].retain_grad()
    weights = torch.rand(1, height, width, channels, dtype=torch.float64)
    (image * weights).sum().backward()

    radii, means2d, conics = gsplat_111_projection(
        s["means"], s["quats"], s["scales"], w2c, K, width, height
    )
    means2d = means2d.detach().requires_grad_()
    tiles_x, tiles_y = (width + 15) // 16, (height + 15) // 16
    _, isect_ids, flatten_ids = gsplat_torch._isect_tiles(
        means2d.detach()[None],
        radii[None, :, None].expand(-1, -1, 2),
        meta["depths"],
        16,
        tiles_x,
        tiles_y,
    )
    offsets = gsplat_torch._isect_offset_encode(isect_ids, 1, tiles_x, tiles_y)
    ref_image, ref_alpha = gsplat_torch._rasterize_to_pixels(
        means2d[None],
        conics[None].detach(),
        s["features"][None],
        s["opacities"][None],
        width,
        height,
        16,
        offsets,
        flatten_ids,
        backgrounds=background,
    )
    (ref_image * weights).sum().backward()

    # a pixel behind one nearly opaque Gaussian keeps T = 1 - 0.999, not 3DGS's 1 - 0.99
    if opacity[0] > 0.85:
        assert float(alpha.detach().max()) > 0.995
    torch.testing.assert_close(image, ref_image, rtol=0, atol=1e-9)
    torch.testing.assert_close(alpha, ref_alpha, rtol=0, atol=1e-9)
    visible = radii > 0
    torch.testing.assert_close(
        meta["means2d"].grad[0][visible], means2d.grad[visible], rtol=1e-6, atol=1e-9
    )


def test_alpha_is_clamped_at_0999():
    """gsplat: alpha = min(0.999, o·exp(-sigma)) (rasterize_to_pixels_fwd.cu:134; 3DGS and
    olatbench's own rasterizer: 0.99): an opaque Gaussian centred on a pixel leaves T = 0.001 there;
    no gradient passes the clamp (rasterize_to_pixels_bwd.cu:207)."""
    w2c = torch.eye(4, dtype=torch.float64)
    K = torch.tensor([[20.0, 0, 8.5], [0, 20.0, 8.5], [0, 0, 1]], dtype=torch.float64)
    opacity = torch.tensor([1.0], dtype=torch.float64, requires_grad=True)
    _, alpha, _ = standin(
        torch.tensor([[0.0, 0.0, 1.0]], dtype=torch.float64),
        torch.tensor([[1.0, 0, 0, 0]], dtype=torch.float64),
        torch.full((1, 3), 0.05, dtype=torch.float64),
        opacity,
        torch.ones(1, 3, dtype=torch.float64),
        w2c,
        K,
        16,
        16,
    )
    assert float(alpha[0, 8, 8, 0]) == pytest.approx(0.999, abs=1e-15)
    alpha[0, 8, 8, 0].backward()
    assert float(opacity.grad) == 0.0


def test_a_pixel_stops_when_its_transmittance_reaches_1e4():
    """gsplat stops a pixel before the Gaussian whose next transmittance is <= 1e-4
    (rasterize_to_pixels_fwd.cu:140; 3DGS: < 1e-4): of two Gaussians centred on a pixel, the second
    taking T to exactly 1e-4, only the first is composited there."""
    pytest.importorskip("gsplat")
    from gsplat_cpu import T_STOP

    # Opacities (= alphas at the pixel centre, where power = 0) found by a random search over 1 - a
    # = i·2⁻⁵³: the float64 product of their (exact) complements is 1e-4 exactly.
    first, second = 0.9718609821300858, 0.9964462156972821
    assert (1.0 - first) * (1.0 - second) == T_STOP and second < 0.999
    w2c = torch.eye(4, dtype=torch.float64)
    # (0, 0, z) -> (8.5, 8.5)
    K = torch.tensor([[20.0, 0, 8.5], [0, 20.0, 8.5], [0, 0, 1]], dtype=torch.float64)
    means = torch.tensor([[0.0, 0.0, 1.0], [0.0, 0.0, 2.0]], dtype=torch.float64)
    quats = torch.tensor([[1.0, 0, 0, 0]] * 2, dtype=torch.float64)
    scales = torch.full((2, 3), 0.02, dtype=torch.float64)
    colours = torch.tensor([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], dtype=torch.float64)
    image, alpha, _ = standin(
        means,
        quats,
        scales,
        torch.tensor([first, second], dtype=torch.float64),
        colours,
        w2c,
        K,
        16,
        16,
    )
    assert float(image[0, 8, 8, 1]) == 0.0  # the second Gaussian is not composited at pixel (8, 8)
    assert float(alpha[0, 8, 8, 0]) == first
    assert float(image[0, 8, 9, 1]) > 0.0  # next to it, where T stays above 1e-4, it is


def test_tile_lists_are_gsplats():
    """gsplat bins a Gaussian to the tiles [floor((m - r)/16), ceil((m + r)/16))
    (isect_tiles.cu:55-64): with its mean 3.05 px right of pixel 15's centre and radius 3 it is in
    tile 0's list, and composited at pixel 15 where its alpha (0.95·exp(-½·3.05²/0.89) = 0.0051) is
    above 1/255, although pixel 15 lies outside its box m ± r."""
    # isotropic 2D variance with the 0.3 low-pass: radius ceil(3·sqrt(0.89 + 0.1)) = 3
    variance = 0.89
    f, z = 20.0, 1.0
    scale = math.sqrt(variance - 0.3) * z / f
    w2c = torch.eye(4, dtype=torch.float64)
    # the mean at (18.55, 8.5)
    K = torch.tensor([[f, 0, 18.55], [0, f, 8.5], [0, 0, 1]], dtype=torch.float64)
    means = torch.tensor([[0.0, 0.0, z]], dtype=torch.float64)
    _, alpha, meta = standin(
        means,
        torch.tensor([[1.0, 0, 0, 0]], dtype=torch.float64),
        torch.full((1, 3), scale, dtype=torch.float64),
        torch.tensor([0.95], dtype=torch.float64),
        torch.ones(1, 3, dtype=torch.float64),
        w2c,
        K,
        32,
        16,
    )
    assert meta["radii"].tolist() == [[3]]
    expected = 0.95 * math.exp(-0.5 * 3.05**2 / variance)
    assert expected > 1 / 255
    assert float(alpha[0, 8, 15, 0]) == pytest.approx(expected, rel=1e-9)
    assert float(alpha[0, 8, 14, 0]) == 0.0  # 4.05 px away: below 1/255


def test_rasterization_refuses_what_it_does_not_implement():
    from olatbench.methods.official.cpu_standins.rasterization import rasterization

    args = (
        torch.zeros(1, 3),
        torch.tensor([[1.0, 0, 0, 0]]),
        torch.ones(1, 3),
        torch.ones(1),
        torch.ones(1, 3),
        torch.eye(4)[None],
        torch.eye(3)[None],
        4,
        4,
    )
    with pytest.raises(
        NotImplementedError, match=r"rasterization\(packed=True\) is not implemented"
    ):
        rasterization(*args)
    with pytest.raises(NotImplementedError, match="render_mode='RGB\\+D'"):
        rasterization(*args, packed=False, render_mode="RGB+D")


# -----------------------------------------------------------------------------------------------
# tinycudann
def test_frequency_encoding_is_the_closed_form():
    encoding = Encoding(3, {"otype": "Frequency", "n_frequencies": 8})
    x = torch.rand(7, 3) * 2 - 1
    out = encoding(x)
    assert encoding.n_output_dims == 48 and out.shape == (7, 48)
    for j in range(48):  # tiny-cuda-nn's frequency kernel, output by output
        dim, level, phase = j // 16, (j // 2) % 8, (j % 2) * math.pi / 2
        expected = torch.sin(x[:, dim] * (2.0**level) * math.pi + phase)
        torch.testing.assert_close(out[:, j], expected, rtol=0, atol=2e-5)


def test_fully_fused_mlp_is_the_padded_bias_free_mlp():
    config = {
        "otype": "FullyFusedMLP",
        "activation": "LeakyReLU",
        "output_activation": "Sigmoid",
        "n_neurons": 64,
        "n_hidden_layers": 3,
    }
    net = Network(105, 1, config)
    # authors' zero-init: no-op
    assert not [m for _, m in net.named_children() if isinstance(m, torch.nn.Linear)]
    assert [tuple(p.shape) for p in net.parameters()] == [(64 * 112 + 64 * 64 * 2 + 16 * 64,)]
    x = torch.randn(5, 105)
    with torch.no_grad():
        w = net.params.detach()
        w1, w2, w3, w4 = (
            w[:7168].view(64, 112),
            w[7168:11264].view(64, 64),
            w[11264:15360].view(64, 64),
            w[15360:].view(16, 64),
        )
        # Identity encoding pads with 1
        h = np.concatenate([x.numpy(), np.ones((5, 7), np.float32)], axis=1)
        for m in (w1, w2, w3):
            h = h @ m.numpy().T
            h = np.where(h > 0, h, 0.01 * h)
        expected = 1 / (1 + np.exp(-(h @ w4.numpy().T)))[:, :1]
    np.testing.assert_allclose(net(x).detach().numpy(), expected, rtol=1e-5, atol=1e-6)
    bound = math.sqrt(6 / (64 + 112))
    # Xavier-uniform range
    assert float(w1.abs().max()) <= bound and float(w1.abs().max()) > 0.9 * bound


@pytest.mark.parametrize(
    "config",
    [
        {
            "otype": "CutlassMLP",
            "activation": "LeakyReLU",
            "output_activation": "Sigmoid",
            "n_neurons": 64,
            "n_hidden_layers": 3,
        },
        {
            "otype": "FullyFusedMLP",
            "activation": "ReLU",
            "output_activation": "Sigmoid",
            "n_neurons": 64,
            "n_hidden_layers": 3,
        },
        {
            "otype": "FullyFusedMLP",
            "activation": "LeakyReLU",
            "output_activation": "Sigmoid",
            "n_neurons": 96,
            "n_hidden_layers": 3,
        },
    ],
)
def test_other_network_configs_are_refused_by_name(config):
    with pytest.raises(NotImplementedError, match=config["otype"]):
        Network(8, 1, config)


def test_other_encodings_are_refused_by_name():
    with pytest.raises(NotImplementedError, match="HashGrid"):
        Encoding(3, {"otype": "HashGrid", "n_levels": 16})


# ------------------------------------------------------------------------------------------ knn,
# save_image
def test_dist_cuda2_is_the_mean_squared_distance_to_three_nearest_neighbours():
    points = torch.rand(500, 3, generator=torch.Generator().manual_seed(5)) - 0.5
    d2 = torch.cdist(points.double(), points.double()) ** 2
    d2.fill_diagonal_(float("inf"))
    expected = d2.topk(3, largest=False).values.mean(1)
    torch.testing.assert_close(distCUDA2(points).double(), expected, rtol=1e-4, atol=1e-9)


def test_save_image_writes_torchvisions_8_bit_values(tmp_path):
    from PIL import Image

    image = torch.rand(3, 6, 5)
    image[0, 0, 0], image[1, 0, 0] = 1.3, -0.2
    save_image(image, tmp_path / "x.png")
    written = np.asarray(Image.open(tmp_path / "x.png"))
    expected = np.floor(np.clip(image.permute(1, 2, 0).numpy() * 255 + 0.5, 0, 255)).astype(
        np.uint8
    )
    assert written.shape == (6, 5, 3) and np.array_equal(written, expected)


# ------------------------------------------------------------------------------------- shim and
# environment
SHIM_PROBE = """
import time
import torch
import gsplat, tinycudann, simple_knn._C, diff_gaussian_rasterization_light, torchvision.utils
assert "cpu_standins" in gsplat.__file__ and gsplat.__version__.startswith("1.1.1")
a = torch.zeros(2, device="cuda")
b = torch.tensor([1.0], device=torch.device("cuda:0"))
c = torch.ones(3).cuda()
d = torch.ones(2).to("cuda")
e = torch.zeros_like(a, device="cuda")
m = torch.nn.Linear(2, 2).cuda()
assert all(t.device.type == "cpu" for t in (a, b, c, d, e, m.weight))
s = torch.cuda.Stream()
s.wait_stream(torch.cuda.current_stream())
torch.cuda.synchronize(); torch.cuda.empty_cache(); torch.cuda.set_device(torch.device("cuda:0"))
with torch.cuda.stream(s):
    f = a + 1
start, end = torch.cuda.Event(enable_timing=True), torch.cuda.Event(enable_timing=True)
start.record(); time.sleep(0.05); end.record()
assert 40 < start.elapsed_time(end) < 5000
assert not torch.cuda.is_available()
print("shim ok")
"""


def test_job_environment_serves_cuda_requests_from_the_cpu_with_the_standins():
    env = job_environment("ssdgs-official", {"PYTHONPATH": "/somewhere"})
    paths = env["PYTHONPATH"].split(os.pathsep)
    assert paths[0] == str(SITE) and paths[-1] == "/somewhere"
    assert env["OLATBENCH_STANDIN_LIGHT"] == "ssdgs-26e4251"
    assert job_environment("gs3-official", {})["OLATBENCH_STANDIN_LIGHT"] == "gs3-83c8daa"
    # nrhints-official gets only the lpips stand-in (tests/test_cpu_standins_lpips.py), not these
    assert "OLATBENCH_STANDIN_LIGHT" not in job_environment(
        "nrhints-official", {"PYTHONPATH": "/x"}
    )
    assert job_environment("nrhints-official", {})["PYTHONPATH"].split(os.pathsep)[0] != str(SITE)
    assert job_environment("gigs-official", {"PYTHONPATH": "/x"}) == {"CUDA_VISIBLE_DEVICES": ""}
    # RNG's forks: tests/test_cpu_standins_rng.py
    rng = job_environment("rng-official", {"PYTHONPATH": "/x"})
    assert (
        rng["PYTHONPATH"].split(os.pathsep)[0] == str(SITE) and "OLATBENCH_STANDIN_LIGHT" not in rng
    )
    done = subprocess.run(
        [sys.executable, "-c", SHIM_PROBE],
        env={**os.environ, **env},
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert "shim ok" in done.stdout
    # without the job environment none of the stand-ins is importable under the real names
    plain = subprocess.run(
        [sys.executable, "-c", "import tinycudann"], capture_output=True, text=True, timeout=600
    )
    assert plain.returncode != 0


# ------------------------------------------------------------------------------------------ the
# device setting
def test_device_setting_comes_from_every_source_and_is_checked(tmp_path):
    from olatbench.methods.official.settings import SettingsError, resolve_settings

    assert resolve_settings("gs3-official", {}, {}, {}).device == "cuda"
    assert resolve_settings("gs3-official", {"device": "CPU"}, {}, {}).device == "cpu"
    assert (
        resolve_settings("gs3-official", {}, {"gs3-official": {"device": "cpu"}}, {}).device
        == "cpu"
    )
    from_env = resolve_settings("gs3-official", {}, {}, {"OLATBENCH_GS3_OFFICIAL_DEVICE": "cpu"})
    assert (
        from_env.device == "cpu" and from_env.sources["device"] == "OLATBENCH_GS3_OFFICIAL_DEVICE"
    )
    with pytest.raises(
        SettingsError, match=r"device must be one of cuda, cpu, not 'tpu' \(--code\)"
    ):
        resolve_settings("gs3-official", {"device": "tpu"}, {}, {})
    boxed = resolve_settings(
        "gs3-official",
        {"device": "cpu", "container": "docker run img python", "checkout": str(tmp_path)},
        {},
        {},
    )
    assert any("device=cpu" in problem and "container" in problem for problem in boxed.problems())


def run_cpu_job(tmp_path: Path, method: str, script: str, probe: str) -> tuple[str, dict, Path]:
    """Plan and run a ``device=cpu`` job of ``method`` on a stand-in checkout whose ``script`` also
    runs the Python lines ``probe`` (printing what the job's interpreter sees); its log,
    results.json's ``official`` block and the checkout."""
    from official_standins import write_checkout
    from test_official import plan, suite_of, write_data

    from olatbench.bench.executors import run_inline
    from olatbench.bench.results import read_results

    data = write_data(tmp_path / "data")
    checkout = write_checkout(tmp_path / "checkout", method)
    with open(checkout / script, "a") as handle:
        handle.write(probe)
    jobs = plan(
        method,
        suite_of("tiny"),
        data,
        tmp_path / "runs",
        checkout=str(checkout),
        python=sys.executable,
        device="cpu",
    )
    [outcome] = run_inline(jobs, progress=False)
    log = Path(jobs[0].folder, "log.txt").read_text()
    assert outcome.status == "done", log
    assert not list(checkout.rglob("sitecustomize.py"))  # nothing written into the checkout
    return log, read_results(os.path.join(jobs[0].folder, "results.json"))["official"], checkout


def test_a_cpu_job_imports_the_standins_and_records_them(tmp_path):
    log, official, checkout = run_cpu_job(
        tmp_path,
        "ssdgs-official",
        "train.py",
        "import gsplat, torch\nprint('gsplat from', gsplat.__file__)\n"
        "print('cuda tensor on', torch.zeros(1, device='cuda').device)\n",
    )
    assert f"gsplat from {SITE / 'gsplat' / '__init__.py'}" in log and "cuda tensor on cpu" in log
    assert official["device"] == "cpu" and official["settings"]["device"] == "cpu"
    assert set(official["standins"]) >= {
        "gsplat",
        "diff_gaussian_rasterization_light",
        "tinycudann",
        "simple_knn",
    }
    assert not (checkout / "gsplat").exists()


@pytest.mark.parametrize("method", ["ssdgs-official", "nrhints-official", "rng-official"])
def test_doctor_checks_the_cpu_environment_against_the_pins(tmp_path, monkeypatch, method):
    """Each method's own stand-ins are imported and its own pins checked (NRHints: its
    requirements.txt; RNG: its environment.yml and the imports it does not list)."""
    import importlib
    import importlib.metadata

    from click.testing import CliRunner
    from official_standins import write_checkout

    from olatbench.cli import main
    from olatbench.methods.official.doctor import CPU_PINS, NRHINTS_CPU_PINS, RNG_CPU_PINS, cpu_pins

    pins = cpu_pins(method)
    assert pins is {"nrhints-official": NRHINTS_CPU_PINS, "rng-official": RNG_CPU_PINS}.get(
        method, CPU_PINS
    )
    monkeypatch.chdir(tmp_path)
    checkout = write_checkout(tmp_path / "clone", method, git=True)
    options = [
        f"{method}.checkout={checkout}",
        f"{method}.python={sys.executable}",
        f"{method}.device=cpu",
    ]
    result = CliRunner().invoke(
        main, ["doctor", *[arg for option in options for arg in ("--code", option)]]
    )
    row = next(line for line in result.output.splitlines() if f"{method}: CPU stand-ins" in line)
    assert f"{method}: GPU" not in result.output and "stand-ins import" in row, row

    def version(name):
        try:
            module = importlib.import_module(name)
        except ImportError:
            return None
        try:
            return getattr(module, "__version__", None) or importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            return "unknown version"

    mismatched = [
        name
        for name, pin in pins.items()
        if version(name) is None or (pin and not str(version(name)).startswith(pin))
    ]
    assert row.strip().startswith("NO" if mismatched else "ok"), (row, mismatched)
    assert all(f"{name} " in row for name in mismatched)
