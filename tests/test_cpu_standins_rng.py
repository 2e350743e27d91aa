"""The CPU stand-ins of RNG's CUDA modules (olatbench.methods.official.cpu_standins.rng_rasterizer,
rng_orthographic, torchmetrics_image) against independent references: a brute-force evaluation of
the fork's forward.cu written here from the CUDA source (per pixel, Gaussians in depth order,
Inria's culling, radius and tile rules), finite differences for the backward, and closed forms / a
direct window loop for the metrics."""

from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest
import torch

from olatbench.methods.official.cpu_standins import SITE, job_environment, standins_for
from olatbench.methods.official.cpu_standins import rng_orthographic as ortho
from olatbench.methods.official.cpu_standins import rng_rasterizer as fork
from olatbench.methods.official.cpu_standins.torchmetrics_image import (
    learned_perceptual_image_patch_similarity,
    peak_signal_noise_ratio,
    structural_similarity_index_measure,
)

CHANNELS = 16


def projection_matrix(
    tanx: float, tany: float, znear: float = 0.01, zfar: float = 100.0
) -> torch.Tensor:
    """RNG's utils/graphics_utils.py getProjectionMatrix (symmetric frustum), row-major."""
    P = torch.zeros(4, 4, dtype=torch.float64)
    P[0, 0], P[1, 1], P[3, 2] = 1 / tanx, 1 / tany, 1.0
    P[2, 2], P[2, 3] = zfar / (zfar - znear), -(zfar * znear) / (zfar - znear)
    return P


def perspective_settings(
    width=40, height=28, tanx=0.32, eye=(0.5, -0.4, 3.0), low_pass=0.3, white=False, modifier=1.0
) -> fork.GaussianRasterizationSettings:
    """A camera looking at the origin, with RNG's column-major matrices (Camera:
    world_view_transform = W2C^T, full_proj_transform = world_view_transform @ P^T)."""
    eye = torch.tensor(eye, dtype=torch.float64)
    forward = -eye / eye.norm()
    right = torch.linalg.cross(forward, torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64))
    right = right / right.norm()
    down = torch.linalg.cross(forward, right)
    w2c = torch.eye(4, dtype=torch.float64)
    w2c[:3, :3] = torch.stack([right, down, forward])
    w2c[:3, 3] = -w2c[:3, :3] @ eye
    tany = tanx * height / width
    view = w2c.T
    return fork.GaussianRasterizationSettings(
        image_height=height,
        image_width=width,
        tanfovx=tanx,
        tanfovy=tany,
        bg=torch.ones(3) if white else torch.zeros(3),
        scale_modifier=modifier,
        viewmatrix=view,
        projmatrix=view @ projection_matrix(tanx, tany).T,
        sh_degree=3,
        campos=eye,
        prefiltered=False,
        debug=False,
        low_pass_filter_radius=low_pass,
    )


def scene(n: int = 14, seed: int = 0, spread: float = 0.5):
    g = torch.Generator().manual_seed(seed)
    means = (torch.rand(n, 3, generator=g, dtype=torch.float64) - 0.5) * 2 * spread
    scales = 0.02 + 0.12 * torch.rand(n, 3, generator=g, dtype=torch.float64)
    quats = torch.randn(n, 4, generator=g, dtype=torch.float64)
    quats = quats / quats.norm(dim=-1, keepdim=True)
    opacities = 0.2 + 0.5 * torch.rand(n, 1, generator=g, dtype=torch.float64)
    colors = torch.rand(n, CHANNELS, generator=g, dtype=torch.float64)
    return means, scales, quats, opacities, colors


def rotation(quats: torch.Tensor) -> torch.Tensor:
    r, x, y, z = quats.unbind(-1)
    return torch.stack(
        [
            1 - 2 * (y * y + z * z),
            2 * (x * y - r * z),
            2 * (x * z + r * y),
            2 * (x * y + r * z),
            1 - 2 * (x * x + z * z),
            2 * (y * z - r * x),
            2 * (x * z - r * y),
            2 * (y * z + r * x),
            1 - 2 * (x * x + y * y),
        ],
        -1,
    ).reshape(-1, 3, 3)


def composite(px, py, cov, depth, visible, opacities, colors, background, width, height):
    """forward.cu renderCUDA per pixel (integer pixel centres): Gaussians nearest first, those whose
    getRect tiles hold the pixel; α = min(0.99, o·exp(power)), skipped when power > 0 or α < 1/255,
    stop before T < 1e-4; returns colour [C, H, W] (+ T·bg), depth Σ z α T and alpha Σ α T
    [1, H, W]."""
    a, b, c = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
    det = a * c - b * b
    conic = torch.stack([c / det, -b / det, a / det], -1)
    mid = 0.5 * (a + c)
    root = torch.sqrt(torch.clamp(mid * mid - det, min=0.1)).detach()
    radius = torch.ceil(3 * torch.sqrt(torch.maximum(mid + root, mid - root))).detach()
    tiles = (math.ceil(width / 16), math.ceil(height / 16))
    ys, xs = torch.meshgrid(
        torch.arange(height, dtype=torch.float64),
        torch.arange(width, dtype=torch.float64),
        indexing="ij",
    )
    T = torch.ones(height, width, dtype=torch.float64)
    done = torch.zeros(height, width, dtype=torch.bool)
    image = torch.zeros(colors.shape[1], height, width, dtype=torch.float64)
    out_depth = torch.zeros(height, width, dtype=torch.float64)
    out_alpha = torch.zeros(height, width, dtype=torch.float64)
    for g in sorted(range(len(depth)), key=lambda i: float(depth[i])):
        p = (float(px[g].detach()), float(py[g].detach()))
        r = float(radius[g])
        lo = [min(tiles[k], max(0, int((p[k] - r) / 16))) for k in (0, 1)]
        hi = [min(tiles[k], max(0, int((p[k] + r + 15) / 16))) for k in (0, 1)]
        if not visible[g] or det[g] == 0 or (hi[0] - lo[0]) * (hi[1] - lo[1]) == 0:
            continue
        in_rect = (
            (xs // 16 >= lo[0]) & (xs // 16 < hi[0]) & (ys // 16 >= lo[1]) & (ys // 16 < hi[1])
        )
        dx, dy = px[g] - xs, py[g] - ys
        power = -0.5 * (conic[g, 0] * dx * dx + conic[g, 2] * dy * dy) - conic[g, 1] * dx * dy
        alpha = torch.clamp(opacities[g, 0] * torch.exp(power), max=0.99)
        active = in_rect & ~done & (power <= 0) & (alpha >= 1 / 255)
        test_T = T * (1 - alpha)
        stop = active & (test_T < 1e-4)
        done = done | stop
        w = torch.where(active & ~stop, alpha * T, torch.zeros_like(T))
        image = image + w[None] * colors[g][:, None, None]
        out_depth = out_depth + w * depth[g].detach()
        out_alpha = out_alpha + w
        T = torch.where(active & ~stop, test_T, T)
    return image + T[None] * background[:, None, None], out_depth[None], out_alpha[None]


def brute_force_perspective(means, scales, quats, opacities, colors, s, pixel_offset=None):
    """The fork's preprocessCUDA + renderCUDA (forward.cu:74-116, 170-255, auxiliary.h:139-160),
    from viewmatrix/projmatrix as the kernel reads them; ``pixel_offset`` (N, 2) is added to the 2D
    means (pixels)."""
    width, height = s.image_width, s.image_height
    hom = torch.cat([means, torch.ones_like(means[:, :1])], 1)
    t = (hom @ s.viewmatrix.double())[:, :3]
    p_hom = hom @ s.projmatrix.double()
    ndc = p_hom[:, :3] / (p_hom[:, 3:] + 1e-7)
    px, py = ((ndc[:, 0] + 1) * width - 1) * 0.5, ((ndc[:, 1] + 1) * height - 1) * 0.5
    if pixel_offset is not None:
        px, py = px + pixel_offset[:, 0], py + pixel_offset[:, 1]
    fx, fy = width / (2 * s.tanfovx), height / (2 * s.tanfovy)
    tz = t[:, 2]
    tx = torch.clamp(t[:, 0] / tz, -1.3 * s.tanfovx, 1.3 * s.tanfovx) * tz
    ty = torch.clamp(t[:, 1] / tz, -1.3 * s.tanfovy, 1.3 * s.tanfovy) * tz
    zero = torch.zeros_like(tz)
    J = torch.stack(
        [
            torch.stack([fx / tz, zero, -fx * tx / tz**2], -1),
            torch.stack([zero, fy / tz, -fy * ty / tz**2], -1),
        ],
        -2,
    )
    rot_w = s.viewmatrix.double()[:3, :3].T
    rs = rotation(quats) * (scales * s.scale_modifier)[:, None, :]
    cov = J @ rot_w @ (rs @ rs.transpose(1, 2)) @ rot_w.T @ J.transpose(1, 2)
    cov = cov + s.low_pass_filter_radius * torch.eye(2, dtype=torch.float64)
    background = torch.zeros(colors.shape[1], dtype=torch.float64)
    background[:3] = s.bg.double()
    return composite(px, py, cov, tz, tz > 0.2, opacities, colors, background, width, height)


@pytest.mark.parametrize(
    ("seed", "low_pass", "white", "modifier"),
    [(0, 0.3, False, 1.0), (1, 0.8, True, 1.0), (2, 0.1, False, 0.7)],
)
def test_rng_fork_forward_matches_brute_force_forward_cu(seed, low_pass, white, modifier) -> None:
    s = perspective_settings(low_pass=low_pass, white=white, modifier=modifier)
    means, scales, quats, opacities, colors = scene(seed=seed)
    means2D = torch.zeros_like(means)
    color, radii, depth, alpha = fork.GaussianRasterizer(s)(
        means3D=means,
        means2D=means2D,
        opacities=opacities,
        colors_precomp=colors,
        scales=scales,
        rotations=quats,
    )
    ref_color, ref_depth, ref_alpha = brute_force_perspective(
        means, scales, quats, opacities, colors, s
    )
    assert color.shape == (CHANNELS, 28, 40) and depth.shape == alpha.shape == (1, 28, 40)
    assert radii.dtype == torch.int32 and int((radii > 0).sum()) >= 10
    # the kernel divides by w + 1e-7 (forward.cu:200), the stand-in by z: 2D means differ by ~1e-7
    # relative
    torch.testing.assert_close(color, ref_color, atol=1e-6, rtol=1e-6)
    # Σ z α T, not divided by alpha
    torch.testing.assert_close(depth, ref_depth, atol=1e-6, rtol=1e-6)
    torch.testing.assert_close(alpha, ref_alpha, atol=1e-6, rtol=1e-6)
    assert (
        float(alpha.max()) > 0.5 and float((depth / alpha.clamp(min=1e-9))[alpha > 0.5].min()) > 2.0
    )


def test_gaussians_are_composited_in_every_pixel_of_their_getrect_tiles() -> None:
    """getRect (auxiliary.h:46-56) truncates (p - r) / 16: a Gaussian centred at p = 24.5 px
    (integer pixel centres) with radius 9 covers tile 0, and lights pixel column 15 (9.5 px away,
    beyond its radius, alpha 0.005 > 1/255), which olatbench's own pixel box [p - r, p + r] would
    leave out."""
    s = perspective_settings(width=48, height=20, low_pass=0.3)
    w2c = s.viewmatrix.double().T
    fx = s.image_width / (2 * s.tanfovx)
    z = float(w2c[2, 3])  # the origin's depth
    # 2D variance 8.6 px²: r = 9
    scales = torch.full((1, 3), math.sqrt(8.6 - 0.3) * z / fx, dtype=torch.float64)
    means = (24.5 - (s.image_width - 1) / 2) * z / fx * w2c[0, :3][None]  # camera x -> 2D mean 24.5
    quats = torch.tensor([[1.0, 0.0, 0.0, 0.0]], dtype=torch.float64)
    opacities = torch.tensor([[0.99]], dtype=torch.float64)
    colors = torch.ones(1, CHANNELS, dtype=torch.float64)
    color, radii, _, _ = fork.GaussianRasterizer(s)(
        means3D=means,
        means2D=torch.zeros_like(means),
        opacities=opacities,
        colors_precomp=colors,
        scales=scales,
        rotations=quats,
    )
    ref, _, _ = brute_force_perspective(means, scales, quats, opacities, colors, s)
    torch.testing.assert_close(color, ref, atol=1e-6, rtol=1e-6)
    assert int(radii[0]) == 9
    # 10.5 px: alpha < 1/255
    assert float(color[0, :, 15].max()) > 1 / 255 and float(color[0, :, 14].max()) == 0


def test_rng_fork_backward_matches_finite_differences() -> None:
    s = perspective_settings(width=24, height=18)
    means, scales, quats, opacities, colors = scene(n=6, seed=3, spread=0.3)
    weights = torch.rand(
        CHANNELS, 18, 24, generator=torch.Generator().manual_seed(9), dtype=torch.float64
    )

    def loss(m, sc, q, o, c):
        color, _, _, _ = fork.GaussianRasterizer(s)(
            means3D=m,
            means2D=torch.zeros_like(m),
            opacities=o,
            colors_precomp=c,
            scales=sc,
            rotations=q,
        )
        return (color * weights).sum()

    inputs = [t.clone().requires_grad_(True) for t in (means, scales, quats, opacities, colors)]
    torch.autograd.gradcheck(loss, inputs, eps=1e-6, atol=1e-5, rtol=1e-4)


def test_means2d_gets_the_gradient_in_inrias_units_and_depth_and_alpha_get_none() -> None:
    """backward.cu:460-461, 545-546: the screen-space gradient is dL/d(pixel mean) × (W/2, H/2); the
    fork's Python backward hands the kernel only the colour's gradient (__init__.py:104-127)."""
    s = perspective_settings()
    means, scales, quats, opacities, colors = scene(seed=4)
    weights = torch.rand(
        CHANNELS, 28, 40, generator=torch.Generator().manual_seed(5), dtype=torch.float64
    )
    means2D = torch.zeros_like(means, requires_grad=True)
    color, _, depth, alpha = fork.GaussianRasterizer(s)(
        means3D=means.clone().requires_grad_(True),
        means2D=means2D,
        opacities=opacities.clone().requires_grad_(True),
        colors_precomp=colors,
        scales=scales,
        rotations=quats,
    )
    assert not depth.requires_grad and not alpha.requires_grad
    (color * weights).sum().backward()
    offset = torch.zeros(len(means), 2, dtype=torch.float64, requires_grad=True)
    ref, _, _ = brute_force_perspective(
        means, scales, quats, opacities, colors, s, pixel_offset=offset
    )
    (ref * weights).sum().backward()
    expected = offset.grad * torch.tensor([40 / 2, 28 / 2], dtype=torch.float64)
    # w + 1e-7, as above
    torch.testing.assert_close(means2D.grad[:, :2], expected, atol=1e-6, rtol=2e-5)
    assert float(means2D.grad[:, :2].abs().max()) > 0 and torch.all(means2D.grad[:, 2] == 0)


def test_rng_fork_refuses_what_its_commands_never_use() -> None:
    s = perspective_settings()
    means, scales, quats, opacities, colors = scene()
    rasterizer = fork.GaussianRasterizer(s)
    with pytest.raises(NotImplementedError, match="shs"):
        rasterizer(
            means3D=means,
            means2D=torch.zeros_like(means),
            opacities=opacities,
            shs=colors,
            scales=scales,
            rotations=quats,
        )
    with pytest.raises(ValueError, match="NUM_CHANNELS"):
        rasterizer(
            means3D=means,
            means2D=torch.zeros_like(means),
            opacities=opacities,
            colors_precomp=colors[:, :3],
            scales=scales,
            rotations=quats,
        )
    shifted = s._replace(
        projmatrix=s.viewmatrix @ (projection_matrix(0.32, 0.2) + torch.eye(4) * 0).T
    )
    with pytest.raises(NotImplementedError, match="symmetric perspective"):
        fork.GaussianRasterizer(shifted)(
            means3D=means,
            means2D=torch.zeros_like(means),
            opacities=opacities,
            colors_precomp=colors,
            scales=scales,
            rotations=quats,
        )


def orthographic_settings(
    width=36, height=30, light=(0.3, 0.5, 0.8)
) -> ortho.GaussianRasterizationSettings:
    """As gaussian_renderer/__init__.py:278-283 builds them for a directional light."""
    light_dir = torch.tensor(light, dtype=torch.float64)
    light_dir = light_dir / light_dir.norm()
    forward = -light_dir
    right = -torch.linalg.cross(forward, torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64))
    right = right / right.norm()
    up = torch.linalg.cross(forward, right)
    return ortho.GaussianRasterizationSettings(
        image_height=height,
        image_width=width,
        light_dir=light_dir,
        cam_center=light_dir * 3.0,
        cam_right=right,
        cam_up=up,
        bg=torch.zeros(3),
        scale_modifier=1.0,
        sh_degree=3,
        prefiltered=False,
        debug=False,
        low_pass_filter_radius=0.3,
        viewmatrix=torch.eye(4),
        projmatrix=torch.eye(4),
        campos=torch.zeros(3),
    )


def brute_force_orthographic(means, scales, quats, opacities, colors, s):
    """The orthographic fork's preprocessCUDA (its forward.cu:74-135, 216-276) + renderCUDA."""
    width, height = s.image_width, s.image_height
    light, centre = s.light_dir.double(), s.cam_center.double()
    right, up = s.cam_right.double(), s.cam_up.double()
    p_cam = means - centre
    depth = p_cam @ light
    in_plane = p_cam - depth[:, None] * light
    x, y = in_plane @ right, in_plane @ up  # / half_plane = 1
    px = torch.clamp((x + 1) / 2 * (width - 1) + 0.5, max=width - 1 + 0.5)
    py = torch.clamp((y + 1) / 2 * (height - 1) + 0.5, max=height - 1 + 0.5)
    rows = torch.stack([right, up, light / light.norm()])
    J = torch.tensor([[width / 2, 0, 0], [0, height / 2, 0]], dtype=torch.float64)
    rs = rotation(quats) * scales[:, None, :]
    cov = J @ rows @ (rs @ rs.transpose(1, 2)) @ rows.T @ J.T + 0.3 * torch.eye(
        2, dtype=torch.float64
    )
    visible = torch.ones(len(means), dtype=torch.bool)  # no near culling (in_frustum removed)
    return composite(
        px,
        py,
        cov,
        depth,
        visible,
        opacities,
        colors,
        torch.zeros(colors.shape[1], dtype=torch.float64),
        width,
        height,
    )


def test_orthographic_forward_matches_brute_force_and_its_backward_fails_as_the_forks() -> None:
    s = orthographic_settings()
    means, scales, quats, opacities, colors = scene(seed=6, spread=0.6)
    color, radii, depth, alpha = ortho.GaussianRasterizer(s)(
        means3D=means,
        means2D=torch.zeros_like(means),
        opacities=opacities,
        colors_precomp=colors,
        scales=scales,
        rotations=quats,
    )
    ref_color, ref_depth, ref_alpha = brute_force_orthographic(
        means, scales, quats, opacities, colors, s
    )
    torch.testing.assert_close(color, ref_color, atol=1e-9, rtol=1e-9)
    torch.testing.assert_close(depth, ref_depth, atol=1e-9, rtol=1e-9)
    torch.testing.assert_close(alpha, ref_alpha, atol=1e-9, rtol=1e-9)
    assert int((radii > 0).sum()) == len(means) and float(alpha.max()) > 0.3
    trained = means.clone().requires_grad_(True)
    color, _, depth, _ = ortho.GaussianRasterizer(s)(
        means3D=trained,
        means2D=torch.zeros_like(means),
        opacities=opacities,
        colors_precomp=colors,
        scales=scales,
        rotations=quats,
    )
    # --shadow_grad lets nothing through this path
    with pytest.raises(AttributeError, match="tanfovx"):
        depth.sum().backward()


def test_torchmetrics_psnr_and_ssim_are_the_closed_form_and_the_window_loop() -> None:
    g = torch.Generator().manual_seed(0)
    target = torch.rand(2, 3, 23, 19, generator=g, dtype=torch.float64)
    preds = (target + 0.1 * torch.randn(target.shape, generator=g, dtype=torch.float64)).clamp(0, 1)
    value_range = float(target.max() - target.min())
    mse = float(((preds - target) ** 2).mean())
    assert float(peak_signal_noise_ratio(preds, target)) == pytest.approx(
        10 * math.log10(value_range**2 / mse), rel=1e-12
    )
    # SSIM by its definition over each 11x11 Gaussian window of the reflect-padded images, centres 5
    # px inside
    p, t = preds.numpy(), target.numpy()
    k = np.exp(-((np.arange(11) - 5.0) ** 2) / (2 * 1.5**2))
    window = np.outer(k, k) / np.outer(k, k).sum()
    data_range = max(p.max() - p.min(), t.max() - t.min())
    c1, c2 = (0.01 * data_range) ** 2, (0.03 * data_range) ** 2
    pad = lambda x: np.pad(x, ((0, 0), (0, 0), (5, 5), (5, 5)), mode="reflect")  # noqa: E731
    pp, tp = pad(p), pad(t)
    per_image = []
    for n in range(2):
        values = []
        for c in range(3):
            for y in range(5, 23 - 5):
                for x in range(5, 19 - 5):
                    a, b = pp[n, c, y : y + 11, x : x + 11], tp[n, c, y : y + 11, x : x + 11]
                    mu_a, mu_b = (window * a).sum(), (window * b).sum()
                    var_a, var_b = (
                        (window * a * a).sum() - mu_a**2,
                        (window * b * b).sum() - mu_b**2,
                    )
                    cov = (window * a * b).sum() - mu_a * mu_b
                    values.append(
                        (2 * mu_a * mu_b + c1)
                        * (2 * cov + c2)
                        / ((mu_a**2 + mu_b**2 + c1) * (var_a + var_b + c2))
                    )
        per_image.append(np.mean(values))
    assert float(structural_similarity_index_measure(preds, target)) == pytest.approx(
        np.mean(per_image), rel=1e-10
    )
    with pytest.raises(NotImplementedError, match="data_range"):
        peak_signal_noise_ratio(preds, target, data_range=1.0)


def test_torchmetrics_lpips_is_olatbenchs_lpips_on_inputs_taken_as_minus_one_to_one() -> None:
    from olatbench.metrics.lpips import lpips

    g = torch.Generator().manual_seed(1)
    a = torch.rand(2, 3, 32, 32, generator=g)
    b = (a + 0.2 * torch.rand(a.shape, generator=g)).clamp(0, 1)
    # normalize=False: the [0, 1] images go in as they are; olatbench's lpips maps [0, 1] to [-1, 1]
    # itself, so it gets (x + 1) / 2 to see the same network inputs
    expected = np.mean(
        [
            lpips(
                ((a[i] + 1) / 2).permute(1, 2, 0).numpy(), ((b[i] + 1) / 2).permute(1, 2, 0).numpy()
            )
            for i in range(2)
        ]
    )
    assert float(learned_perceptual_image_patch_similarity(a, b)) == pytest.approx(
        expected, rel=1e-4, abs=1e-6
    )
    # > 1 passes, as in 1.4.0
    assert math.isfinite(float(learned_perceptual_image_patch_similarity(a * 3, b)))
    with pytest.raises(ValueError, match="from -1"):
        learned_perceptual_image_patch_similarity(a - 2, b)


PROBE = """
import sys, torch
import diff_gaussian_rasterization, diff_gaussian_rasterization_orthographic, simple_knn._C, torchvision.utils
from torchmetrics.functional.image import peak_signal_noise_ratio, learned_perceptual_image_patch_similarity
x = torch.zeros(2, 3).cuda()
torch.save((x + 1, 30), sys.argv[1])
(loaded, iteration) = torch.load(sys.argv[1], map_location='cuda')  # train.py:46, the stage-1 checkpoint
assert iteration == 30 and loaded.device.type == "cpu" and float(loaded.sum()) == 6
print(diff_gaussian_rasterization.__file__, diff_gaussian_rasterization_orthographic.__file__, x.device)
"""  # noqa: E501


def test_an_rng_job_imports_its_standins_from_the_site_folder(tmp_path) -> None:
    assert standins_for("rng-official") == (
        "diff_gaussian_rasterization",
        "diff_gaussian_rasterization_orthographic",
        "simple_knn",
        "torchvision",
        "torchmetrics",
        "sitecustomize",
    )
    env = {**os.environ, **job_environment("rng-official", {})}
    out = subprocess.run(
        [sys.executable, "-c", PROBE, str(tmp_path / "chkpnt30.pth")],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr
    assert str(SITE / "diff_gaussian_rasterization") in out.stdout and out.stdout.strip().endswith(
        "cpu"
    )
