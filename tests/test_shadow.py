"""Light-view visibility pass: light camera, brute-force 3D shadow rays, torch vs C++, offsets,
weights."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from olatbench.gaussians.backends import cpu_backend_status
from olatbench.gaussians.backends.cpu import shadow_gather_cpu
from olatbench.gaussians.projection import quat_to_rotmat
from olatbench.gaussians.shadow import (
    OFFICIAL_KERNEL,
    _camera_matched_focal_on_device,
    _gather_torch,
    _light_camera_on_device,
    camera_matched_focal,
    light_camera,
    shadow_gather,
)
from olatbench.gaussians.tiles import bin_gaussians

IDENTITY = [1.0, 0.0, 0.0, 0.0]


def _scene(rows: list[tuple[tuple[float, float, float], float, float]]):
    """Isotropic Gaussians from (centre, sigma, opacity) rows."""
    means = torch.tensor([r[0] for r in rows], dtype=torch.float64)
    scales = torch.tensor([[r[1]] * 3 for r in rows], dtype=torch.float64)
    opacities = torch.tensor([r[2] for r in rows], dtype=torch.float64)
    quats = torch.tensor([IDENTITY] * len(rows), dtype=torch.float64)
    return means, quats, scales, opacities


def _brute_force_visibility(
    means, quats, scales, opacities, light, w2c, K, g, mode, radius_px=2.0, offset=0.0
):
    """Average over the pixels near g's projected centre of Π(1 - α_k(ray)) over the Gaussians in
    front.

    α_k(ray) = min(0.99, o_k · max_t G_k(light + t·dir)): the exact 3D maximum of Gaussian k along
    the shadow ray (closed form), independent of the splatting approximation under test.
    """
    m = means.numpy()
    cov = (
        quat_to_rotmat(quats)
        @ torch.diag_embed(scales**2)
        @ quat_to_rotmat(quats).transpose(-1, -2)
    ).numpy()
    precision = np.linalg.inv(cov)
    light = light.numpy()
    w2c, K = w2c.double().numpy(), K.double().numpy()
    cam = w2c[:3, :3] @ m[g] + w2c[:3, 3]
    centre = (K @ cam)[:2] / cam[2]
    key = ((m - light) ** 2).sum(1)

    # max over t ≥ 0 of exp(-½ (t d - m)ᵀ A (t d - m)), m relative to the light
    def peak(k, direction):
        rel = m[k] - light
        a = precision[k]
        dad, dam = direction @ a @ direction, direction @ a @ rel
        t = max(dam / dad, 0.0)  # the shadow ray starts at the light
        offset = t * direction - rel
        return math.exp(-0.5 * (offset @ a @ offset))

    total, norm = 0.0, 0.0
    for py in range(int(centre[1] - radius_px) - 1, int(centre[1] + radius_px) + 2):
        for px in range(int(centre[0] - radius_px) - 1, int(centre[0] + radius_px) + 2):
            if (px + 0.5 - centre[0]) ** 2 + (py + 0.5 - centre[1]) ** 2 > radius_px**2:
                continue
            direction = w2c[:3, :3].T @ np.linalg.solve(K, [px + 0.5, py + 0.5, 1.0])
            transmittance = 1.0
            for k in np.argsort(key, kind="stable"):
                if k == g or key[k] >= key[g] - offset:
                    continue
                alpha = min(0.99, opacities[k].item() * peak(k, direction))
                if alpha >= 1 / 255:
                    transmittance *= 1 - alpha
            rho = peak(g, direction) if mode == "density" else 1.0
            total += rho * transmittance
            norm += rho
    return total / norm


LIGHT = torch.tensor([0.0, -4.0, 0.3], dtype=torch.float64)
TARGET = torch.tensor([0.0, 0.5, 0.0], dtype=torch.float64)


def _occluder_scene():
    return _scene([
        ((0.0, 0.0, 0.0), 0.15, 0.6),  # 0 occluder
        # 1 receiver behind it (slightly off the occluder's centre line)
        ((0.0, 1.0, 0.08), 0.05, 0.9),
        ((0.9, 1.0, 0.0), 0.05, 0.9),  # 2 receiver with nothing in front
        ((0.0, -5.0, 0.3), 0.05, 0.9),  # 3 behind the light: unseen
    ])  # fmt: skip


BACKENDS = [
    "torch",
    pytest.param(
        "cpu",
        marks=pytest.mark.skipif(not cpu_backend_status()[0], reason="C++ backend unavailable"),
    ),
]


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("mode", ["uniform", "density"])
def test_occluder_receiver_matches_brute_force_rays(mode, backend):
    scene = _occluder_scene()
    result = shadow_gather(
        *scene, LIGHT, TARGET, resolution=128, backend=backend, mode=mode, scene_radius=1.5
    )
    assert result.backend == backend
    w2c, K, _, _ = light_camera(LIGHT, TARGET, scene_radius=1.5, resolution=128)
    expected = _brute_force_visibility(*scene, LIGHT, w2c, K, g=1, mode=mode)
    assert 0.35 < expected < 0.75  # genuinely shadowed, by roughly 1 - α_occluder
    assert abs(float(result.visibility[1]) - expected) < 0.02
    # nothing in front of the occluder
    assert float(result.visibility[0]) == pytest.approx(1.0, abs=1e-6)
    assert float(result.visibility[2]) == pytest.approx(1.0, abs=1e-6)
    assert result.seen.tolist() == [True, True, True, False]
    assert float(result.visibility[3]) == 0.0 and float(result.weight[3]) == 0.0


def test_hint_is_one_minus_occluder_alpha_on_the_centre_line():
    # both on one ray from the light
    scene = _scene([((0.0, 0.0, 0.3), 0.3, 0.7), ((0.0, 1.0, 0.3), 0.05, 0.9)])
    result = shadow_gather(*scene, LIGHT, TARGET, resolution=128, backend="torch", scene_radius=1.5)
    assert float(result.visibility[1]) == pytest.approx(1 - 0.7, abs=0.03)


def test_depth_offset_excludes_near_coplanar_gaussians():
    # Two overlapping Gaussians whose squared distances to the light differ by ~0.03.
    scene = _scene([((0.0, 0.5, 0.3), 0.2, 0.8), ((0.0, 0.50332, 0.3), 0.2, 0.8)])
    plain = shadow_gather(*scene, LIGHT, TARGET, resolution=64, backend="torch", scene_radius=1.0)
    assert float(plain.visibility[1]) == pytest.approx(0.2, abs=0.03)
    offset = shadow_gather(
        *scene, LIGHT, TARGET, resolution=64, backend="torch", scene_radius=1.0, depth_offset=0.05
    )
    assert float(offset.visibility[1]) == pytest.approx(1.0, abs=1e-6)
    small = shadow_gather(
        *scene, LIGHT, TARGET, resolution=64, backend="torch", scene_radius=1.0, depth_offset=0.01
    )
    assert float(small.visibility[1]) == pytest.approx(0.2, abs=0.03)
    w2c, K, _, _ = light_camera(LIGHT, TARGET, scene_radius=1.0, resolution=64)
    for off in (0.0, 0.05):
        expected = _brute_force_visibility(*scene, LIGHT, w2c, K, g=1, mode="uniform", offset=off)
        got = shadow_gather(
            *scene,
            LIGHT,
            TARGET,
            resolution=64,
            backend="torch",
            scene_radius=1.0,
            depth_offset=off,
        )
        assert abs(float(got.visibility[1]) - expected) < 0.02


def test_weight_of_a_lone_gaussian_is_its_splat_integral():
    scene = _scene([((0.0, 0.5, 0.0), 0.1, 0.5)])
    result = shadow_gather(*scene, LIGHT, TARGET, resolution=256, backend="torch", scene_radius=1.0)
    w2c, K, _, _ = light_camera(LIGHT, TARGET, scene_radius=1.0, resolution=256)
    depth = float((w2c[:3, :3].double() @ scene[0][0] + w2c[:3, 3].double())[2])
    sigma_px = 0.1 * float(K[0, 0]) / depth
    # o · ∫ G over the (low-pass widened) 2D Gaussian
    integral = 0.5 * 2 * math.pi * (sigma_px**2 + 0.3)
    assert sigma_px > 5
    assert float(result.weight[0]) == pytest.approx(integral, rel=0.03)


def test_footprint_mode_averages_the_whole_splat():
    # A small occluder covers only the receiver's centre: the 2-px disc is darker than the whole
    # footprint.
    scene = _scene([((0.0, 0.0, 0.3), 0.02, 0.95), ((0.0, 1.0, 0.3), 0.15, 0.9)])
    disc = shadow_gather(
        *scene, LIGHT, TARGET, resolution=128, backend="torch", scene_radius=1.2, mode="density"
    )
    full = shadow_gather(
        *scene, LIGHT, TARGET, resolution=128, backend="torch", scene_radius=1.2, mode="footprint"
    )
    assert float(disc.visibility[1]) < 0.5 < float(full.visibility[1]) < 1.0


def _pixel_size_of_a_sphere(
    eye: torch.Tensor, target: torch.Tensor, radius: float, focal: float
) -> float:
    """Projected radius (px) of the sphere silhouette around ``target`` seen from ``eye`` with
    ``focal``."""
    return focal * math.tan(math.asin(radius / float((target - eye).norm())))


def test_camera_matched_focal_shows_the_scene_at_the_camera_pixel_scale():
    target = torch.tensor([0.3, -0.2, 0.1], dtype=torch.float64)
    camera = target + torch.tensor([0.0, -4.0, 1.0], dtype=torch.float64)
    light = target + torch.tensor([5.0, 3.0, 6.0], dtype=torch.float64)
    fx, width = 300.0, 400
    focal = camera_matched_focal(fx, width, 100, camera, light, target)
    # a small sphere at the target spans the same fraction of both images (rescaled from 400 px to
    # 100 px)
    in_camera = _pixel_size_of_a_sphere(camera, target, 0.05, fx) / width
    in_light = _pixel_size_of_a_sphere(light, target, 0.05, focal) / 100
    assert in_light == pytest.approx(in_camera, rel=1e-3)
    assert focal == pytest.approx(
        fx * 100 / width * float((light - target).norm() / (camera - target).norm())
    )
    # a light nearer than the camera widens the view, capped at 120°
    near = camera_matched_focal(
        fx, width, 100, camera, target + torch.tensor([0.0, 0.0, 0.05]), target
    )
    assert 2 * math.degrees(math.atan(50 / near)) == pytest.approx(120.0)
    with pytest.raises(ValueError, match="camera away from the target"):
        camera_matched_focal(fx, width, 100, target, light, target)


def test_light_camera_fits_the_sphere_and_handles_parallel_up():
    light = torch.tensor([3.0, -2.0, 1.0])
    target = torch.tensor([0.2, 0.1, -0.1])
    w2c, K, width, _ = light_camera(light, target, scene_radius=0.8, resolution=100)
    rot = w2c[:3, :3].double()
    torch.testing.assert_close(rot @ rot.T, torch.eye(3, dtype=torch.float64), atol=1e-6, rtol=0)
    cam = rot @ target.double() + w2c[:3, 3].double()
    uv = (K.double() @ cam)[:2] / cam[2]
    torch.testing.assert_close(
        uv, torch.tensor([50.0, 50.0], dtype=torch.float64), atol=1e-4, rtol=0
    )
    # a point on the sphere's silhouette (tangent from the light) lands just inside the border
    distance = float((target - light).norm())
    half = math.asin(0.8 / distance)
    assert 0.5 * width / float(K[0, 0]) == pytest.approx(math.tan(half * 1.05), rel=1e-5)
    above = light_camera(torch.tensor([0.0, 0.0, 5.0]), torch.zeros(3), scene_radius=1.0)[0][
        :3, :3
    ].double()
    torch.testing.assert_close(
        above @ above.T, torch.eye(3, dtype=torch.float64), atol=1e-6, rtol=0
    )
    assert float(above[2] @ torch.tensor([0.0, 0.0, -1.0], dtype=torch.float64)) == pytest.approx(
        1.0
    )
    fixed = light_camera(light, target, scene_radius=0.8, resolution=64, focal_px=80.0)[1]
    assert float(fixed[0, 0]) == 80.0 and float(fixed[1, 1]) == 80.0 and float(fixed[0, 2]) == 32.0
    inside = light_camera(
        torch.tensor([0.0, 0.0, 0.5]), torch.zeros(3), scene_radius=1.0, resolution=100
    )[1]
    assert 2 * math.degrees(math.atan(50 / float(K[0, 0]))) < 120.0
    assert 2 * math.degrees(math.atan(50 / float(inside[0, 0]))) == pytest.approx(120.0)


@pytest.mark.parametrize("case", ["fitted", "inside", "parallel up", "focal", "tensor radius"])
def test_the_gpu_framing_computed_on_the_device_equals_the_host_framing(case):
    """The light camera and the camera-matched focal length a GPU computes on the device
    (run here on CPU tensors) equal the host's (numpy look-at and inverse, Python floats) to float32
    rounding."""
    light, target = torch.tensor([3.0, -2.0, 1.0]), torch.tensor([0.2, 0.1, -0.1])
    options = {"scene_radius": 0.8, "resolution": 100}
    if case == "inside":
        light, options["scene_radius"] = torch.tensor([0.0, 0.0, 0.5]), 1.0
    elif case == "parallel up":
        light, target = torch.tensor([0.0, 0.0, 5.0]), torch.zeros(3)
    elif case == "focal":
        options["focal_px"] = 80.0
    host = light_camera(light, target, **options)
    if case == "tensor radius":
        options["scene_radius"] = torch.tensor(0.8)
    device = _light_camera_on_device(
        light,
        target,
        options.get("scene_radius", 1.0),
        options["resolution"],
        (0.0, 0.0, 1.0),
        1.05,
        options.get("focal_px"),
    )
    for got, want in zip(device[:2], host[:2], strict=True):
        assert got.dtype == want.dtype == torch.float32
        torch.testing.assert_close(got, want, atol=1e-6, rtol=1e-6)
    assert device[2:] == host[2:]
    camera = target + torch.tensor([0.0, -4.0, 1.0])
    for fx in (300.0, torch.tensor(300.0)):
        on_device = _camera_matched_focal_on_device(fx, 400, 100, camera, light, target)
        assert float(on_device) == pytest.approx(
            camera_matched_focal(300.0, 400, 100, camera, light, target), rel=1e-12
        )


@pytest.mark.skipif(not cpu_backend_status()[0], reason="C++ backend unavailable")
def test_torch_reference_equals_cpp_kernel():
    g = torch.Generator().manual_seed(0)
    n = 400
    means = torch.rand(n, 3, generator=g) * 1.6 - 0.8
    quats = torch.randn(n, 4, generator=g)
    scales = torch.rand(n, 3, generator=g) * 0.08 + 0.005
    opacities = torch.rand(n, generator=g)
    light = torch.tensor([0.4, -3.0, 1.2])
    args = (means, quats, scales, opacities, light, torch.zeros(3))
    ref = shadow_gather(*args, resolution=96, backend="torch")
    cpp = shadow_gather(*args, resolution=96, backend="cpu")
    auto = shadow_gather(*args, resolution=96)
    assert cpp.backend == "cpu" and auto.backend == "cpu" and ref.backend == "torch"
    assert (
        torch.equal(ref.seen, cpp.seen)
        and bool(ref.seen.any())
        and 0.05 < float(ref.visibility.mean()) < 0.95
    )
    torch.testing.assert_close(ref.visibility, cpp.visibility, atol=2e-5, rtol=0)
    torch.testing.assert_close(ref.weight, cpp.weight, atol=1e-3, rtol=1e-4)
    # the official options (density mode) run on the C++ kernel too; the footprint mode is
    # torch-only: auto falls back, an explicit cpu request is refused
    assert shadow_gather(*args, resolution=32, **OFFICIAL_KERNEL).backend == "cpu"
    assert shadow_gather(*args, resolution=32, mode="footprint").backend == "torch"
    with pytest.raises(ValueError, match="C\\+\\+ light pass implements"):
        shadow_gather(*args, resolution=32, backend="cpu", mode="footprint")


def _layered_scene(seed: int, dtype: torch.dtype):
    """Random Gaussians in a slab facing the light: many overlap nearly coplanar neighbours
    (offsets matter)."""
    g = torch.Generator().manual_seed(seed)
    n = 300
    means = torch.rand(n, 3, generator=g, dtype=torch.float64) * torch.tensor([1.6, 0.3, 1.6]) - 0.8
    quats = torch.randn(n, 4, generator=g, dtype=torch.float64)
    scales = torch.rand(n, 3, generator=g, dtype=torch.float64) * 0.1 + 0.01
    opacities = torch.rand(n, generator=g, dtype=torch.float64) * 0.8 + 0.1
    light = torch.tensor([0.3, -3.0, 0.4], dtype=torch.float64)
    return tuple(t.to(dtype) for t in (means, quats, scales, opacities, light, torch.zeros(3)))


@pytest.mark.skipif(not cpu_backend_status()[0], reason="C++ backend unavailable")
@pytest.mark.parametrize("mode", ["uniform", "density"])
@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_cpp_kernel_with_depth_offset_equals_torch_reference(dtype, mode):
    args = _layered_scene(3, dtype)
    plain = shadow_gather(*args, resolution=64, backend="cpu", mode=mode)
    atol = 1e-6 if dtype == torch.float64 else 2e-5
    if mode == "density":  # a genuinely different average from the uniform one
        uniform = shadow_gather(*args, resolution=64, backend="cpu")
        assert float((plain.visibility - uniform.visibility).abs().max()) > 1e-2
    for offset in (0.0, 0.015, 0.3, 3.0):
        # auto picks the C++ kernel
        cpp = shadow_gather(*args, resolution=64, depth_offset=offset, mode=mode)
        ref = shadow_gather(*args, resolution=64, backend="torch", depth_offset=offset, mode=mode)
        assert cpp.backend == "cpu" and ref.backend == "torch"
        assert torch.equal(cpp.seen, ref.seen) and int(cpp.seen.sum()) > 250
        torch.testing.assert_close(
            cpp.visibility, ref.visibility, atol=atol, rtol=0, msg=f"offset {offset}"
        )
        # the weight ignores the offset
        torch.testing.assert_close(cpp.weight, plain.weight, atol=0, rtol=0)
        changed = (cpp.visibility - plain.visibility).abs()
        if offset == 0.0:
            assert torch.equal(cpp.visibility, plain.visibility)
        else:  # the offset genuinely changes the hint (more light reaches near-coplanar receivers)
            assert int((changed > 1e-3).sum()) >= 5 and bool(
                (cpp.visibility >= plain.visibility - atol).all()
            )
    assert float(changed.mean()) > 0.1  # offset 3.0 removes most occluders
    # An offset below float32 resolution excludes nothing more (no equal keys here): the lagging
    # transmittance replays the main one bit for bit.
    tiny = shadow_gather(*args, resolution=64, backend="cpu", depth_offset=1e-30, mode=mode)
    assert torch.equal(tiny.visibility, plain.visibility)


def _per_pixel_gather(means2d, conics, opacities, keys, bins, offset, radius=2.0):
    """Python loop over pixels: for each Gaussian g near a pixel, replay g's tile list up to g
    keeping only the Gaussians j with float32(key_j) < float32(key_g - offset) (all of them when
    offset = 0). Returns the uniform sums (Σ T, pixel count) and the density-weighted ones
    (Σ ρ T, Σ ρ with ρ = exp(power_g))."""
    n = means2d.shape[0]
    vis, cnt, vis_rho, norm = [0.0] * n, [0] * n, [0.0] * n, [0.0] * n
    m, con, op, key = means2d.tolist(), conics.tolist(), opacities.tolist(), keys.tolist()

    def power_at(j, x, y):
        dx, dy = m[j][0] - x - 0.5, m[j][1] - y - 0.5
        return -0.5 * (con[j][0] * dx * dx + con[j][2] * dy * dy) - con[j][1] * dx * dy

    def alpha_at(j, x, y):
        power = power_at(j, x, y)
        alpha = 0.0 if power > 0 else min(0.99, op[j] * math.exp(power))
        return alpha if alpha >= 1 / 255 else 0.0

    for t in range(bins.num_tiles):
        ids = bins.gaussian_ids[bins.offsets[t] : bins.offsets[t + 1]].tolist()
        tx, ty = t % bins.tiles_x, t // bins.tiles_x
        for y in range(ty * 16, min(bins.height, ty * 16 + 16)):
            for x in range(tx * 16, min(bins.width, tx * 16 + 16)):
                for position, g in enumerate(ids):
                    if (m[g][0] - x - 0.5) ** 2 + (m[g][1] - y - 0.5) ** 2 > radius * radius:
                        continue
                    threshold = np.float32(key[g] - offset)
                    T = 1.0
                    for j in ids[:position]:
                        if offset > 0 and not np.float32(key[j]) < threshold:
                            continue
                        alpha = alpha_at(j, x, y)
                        if T * (1 - alpha) < 1e-4:
                            T = 0.0
                            break
                        T *= 1 - alpha
                    vis[g] += T
                    cnt[g] += 1
                    rho = math.exp(power_at(g, x, y))
                    vis_rho[g] += rho * T
                    norm[g] += rho
    return (
        torch.tensor(vis, dtype=torch.float64),
        torch.tensor(cnt, dtype=torch.int32),
        torch.tensor(vis_rho, dtype=torch.float64),
        torch.tensor(norm, dtype=torch.float64),
    )


def _non_monotone_stack_keys(offset: float) -> list[float]:
    """Keys of M, L, a, b (list order): float32(key_a) = float32(key_b) = 1, but key_a's threshold
    float32(key_a - offset) is above key_b's, and float32(key_L) equals key_b's: L is in front of a,
    not of b."""
    same = [x for x in (1.0 + j * 2.0**-28 for j in range(-8, 17)) if np.float32(x) == 1.0]
    a = max(same, key=lambda x: np.float32(x - offset))
    b = min(same, key=lambda x: np.float32(x - offset))
    assert np.float32(a - offset) > np.float32(b - offset)
    return [0.1, float(np.float32(b - offset)), a, b]


@pytest.mark.skipif(not cpu_backend_status()[0], reason="C++ backend unavailable")
@pytest.mark.parametrize("offset", [0.0, 0.125, 0.3])
def test_cpp_depth_offset_matches_per_pixel_loop(offset):
    """Keys on a 1/16 grid (exact in float32) with float64 jitter below float32 resolution: offset
    1/8 puts thresholds exactly on other keys (strict comparison). A stack of 4 Gaussians at one
    spot has keys whose thresholds are not monotone along the list (equal float32 keys, the later
    one's threshold lower), which the kernel handles by replaying its lagging transmittance."""
    g = torch.Generator().manual_seed(7)
    n = 40
    means2d = torch.rand(n, 2, generator=g, dtype=torch.float64) * torch.tensor([30.0, 32.0])
    sigma = torch.rand(n, 2, generator=g, dtype=torch.float64) * 3.0 + 0.6
    corr = torch.rand(n, generator=g, dtype=torch.float64) * 1.2 - 0.6
    cov = torch.stack([sigma[:, 0] ** 2, corr * sigma[:, 0] * sigma[:, 1], sigma[:, 1] ** 2], dim=1)
    opacities = torch.rand(n, generator=g, dtype=torch.float64) * 0.9 + 0.05
    jitter = (torch.rand(n, generator=g, dtype=torch.float64) * 2 - 1) * 2.0**-30
    keys = 1.0 + torch.randint(0, 16, (n,), generator=g).double() / 16 + jitter
    stack_keys = _non_monotone_stack_keys(offset or 0.125)
    # A second stack: 5 opaque occluders in front of a receiver (keys far apart): pixels near its
    # centre stop (T < 1e-4) inside the receiver's front prefix, so the lagging state must stop
    # there too.
    means2d = torch.cat(
        [means2d, torch.tensor([[40.0, 8.0]] * 4 + [[40.0, 24.0]] * 6, dtype=torch.float64)]
    )
    cov = torch.cat([cov, torch.tensor([[9.0, 0.0, 9.0]] * 10, dtype=torch.float64)])
    stack_opacities = [0.5, 0.6, 0.7, 0.8] + [0.99] * 5 + [0.9]
    opacities = torch.cat([opacities, torch.tensor(stack_opacities, dtype=torch.float64)])
    keys = torch.cat(
        [keys, torch.tensor([*stack_keys, 0.02, 0.03, 0.04, 0.05, 0.06, 1.9], dtype=torch.float64)]
    )
    det = cov[:, 0] * cov[:, 2] - cov[:, 1] ** 2
    conics = torch.stack([cov[:, 2] / det, -cov[:, 1] / det, cov[:, 0] / det], dim=1)
    radii = torch.ceil(3 * torch.sqrt(torch.maximum(cov[:, 0], cov[:, 2]))).long()
    bins = bin_gaussians(means2d, radii, keys, 48, 32)

    got = shadow_gather_cpu(
        means2d, conics, opacities, bins, sort_keys=keys, depth_offset=offset, threads=2
    )
    serial = shadow_gather_cpu(
        means2d, conics, opacities, bins, sort_keys=keys, depth_offset=offset, threads=1
    )
    assert torch.equal(got.vis_sum, serial.vis_sum)  # deterministic across thread counts
    vis, cnt, vis_rho, norm = _per_pixel_gather(means2d, conics, opacities, keys, bins, offset)
    assert torch.equal(got.count, cnt) and int((cnt > 0).sum()) == n + 10
    torch.testing.assert_close(got.vis_sum, vis, rtol=1e-10, atol=1e-12)
    assert torch.equal(got.norm, cnt.double())
    density = shadow_gather_cpu(
        means2d,
        conics,
        opacities,
        bins,
        sort_keys=keys,
        depth_offset=offset,
        threads=2,
        density=True,
    )
    assert torch.equal(density.count, cnt) and torch.equal(density.weight, got.weight)
    torch.testing.assert_close(density.vis_sum, vis_rho, rtol=1e-10, atol=1e-12)
    torch.testing.assert_close(density.norm, norm, rtol=1e-10, atol=1e-12)
    # the density weighting genuinely differs from the plain mean (ρ < 1 off the mean)
    assert float((density.vis_sum / density.norm - vis / cnt).abs().max()) > 1e-2
    stack = (got.vis_sum / got.count)[n:]
    if offset > 0:  # b sees only M; a sees M and L
        assert float(stack[3]) > float(stack[2]) + 0.2 and float(stack[0]) == 1.0
    # the receiver behind the opaque stack: its pixels stopped (T < 1e-4)
    assert float(stack[9]) < 1e-3
    plain = shadow_gather_cpu(means2d, conics, opacities, bins)
    assert torch.equal(got.weight, plain.weight)


@pytest.mark.skipif(not cpu_backend_status()[0], reason="C++ backend unavailable")
@pytest.mark.parametrize("offset", [0.0, 0.05])
def test_gaussians_behind_stopped_pixels_match_the_torch_reference(offset):
    """A wall of opaque Gaussians stops every pixel of x < 20 px (T < 1e-4). Behind it: a small
    Gaussian whose whole box has stopped (visibility and weight 0), and a wide one centred behind
    the wall whose box reaches past the wall's edge: its sampling disc has stopped, but the open
    part of its box must still be composited (weight > 0, and it shades a third Gaussian beside the
    wall). A kernel that skipped Gaussians by their disc alone would fail here."""
    wall = [(x + 0.5, y + 0.5) for x in range(20) for y in range(32)]
    means2d = torch.tensor([*wall, (8.0, 16.0), (16.0, 8.0), (23.0, 8.0)], dtype=torch.float64)
    n_wall = len(wall)
    sigma = torch.tensor([1.5] * n_wall + [0.8, 3.5, 1.0], dtype=torch.float64)
    conics = torch.stack([sigma**-2, torch.zeros_like(sigma), sigma**-2], dim=1)
    opacities = torch.tensor([0.99] * n_wall + [0.9, 0.9, 0.9], dtype=torch.float64)
    keys = torch.tensor(
        [0.1 + 0.001 * i for i in range(n_wall)] + [1.0, 1.1, 1.2], dtype=torch.float64
    )
    radii = torch.ceil(3 * sigma).long()
    bins = bin_gaussians(means2d, radii, keys, 32, 32)

    got = shadow_gather_cpu(
        means2d, conics, opacities, bins, sort_keys=keys, depth_offset=offset, threads=2
    )
    vis, count, weight = _gather_torch(
        means2d, conics, opacities, keys, bins, "uniform", 2.0, offset
    )
    assert torch.equal(got.count, count.to(torch.int32))
    torch.testing.assert_close(got.vis_sum, vis, rtol=1e-10, atol=1e-12)
    torch.testing.assert_close(got.weight, weight, rtol=1e-10, atol=1e-12)
    hidden, straddling, open_receiver = n_wall, n_wall + 1, n_wall + 2
    assert float(got.vis_sum[hidden]) == 0.0 and float(got.weight[hidden]) == 0.0
    assert float(got.vis_sum[straddling]) == 0.0 and float(got.weight[straddling]) > 0.05
    # the straddling Gaussian's open part shades the receiver beside the wall: without it, more
    # light arrives
    keep = torch.arange(len(means2d)) != straddling
    without = shadow_gather_cpu(
        means2d[keep],
        conics[keep],
        opacities[keep],
        bin_gaussians(means2d[keep], radii[keep], keys[keep], 32, 32),
    )
    receiver_vis = float(got.vis_sum[open_receiver] / got.count[open_receiver])
    assert receiver_vis < float(without.vis_sum[-1] / without.count[-1]) - 0.02


def test_bad_arguments():
    scene = _occluder_scene()
    with pytest.raises(ValueError, match="unknown shadow mode"):
        shadow_gather(*scene, LIGHT, TARGET, mode="paper")
    with pytest.raises(ValueError, match="depth_offset must be"):
        shadow_gather(*scene, LIGHT, TARGET, depth_offset=float("nan"))
    if cpu_backend_status()[0]:
        flat = torch.zeros(2, 2, dtype=torch.float64)
        bins = bin_gaussians(
            flat, torch.ones(2, dtype=torch.int64), torch.ones(2, dtype=torch.float64), 8, 8
        )
        with pytest.raises(ValueError, match="needs sort_keys"):
            shadow_gather_cpu(
                flat, torch.ones(2, 3, dtype=torch.float64), torch.ones(2), bins, depth_offset=0.1
            )
    with pytest.raises(ValueError, match="coincides with the target"):
        shadow_gather(*scene, TARGET, TARGET)
