"""Light-view visibility pass: light camera, brute-force 3D shadow rays, torch vs C++, offsets, weights."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from olatbench.gaussians.backends import cpu_backend_status
from olatbench.gaussians.projection import quat_to_rotmat
from olatbench.gaussians.shadow import OFFICIAL_KERNEL, light_camera, shadow_gather

IDENTITY = [1.0, 0.0, 0.0, 0.0]


def _scene(rows: list[tuple[tuple[float, float, float], float, float]]):
    """Isotropic Gaussians from (centre, sigma, opacity) rows."""
    means = torch.tensor([r[0] for r in rows], dtype=torch.float64)
    scales = torch.tensor([[r[1]] * 3 for r in rows], dtype=torch.float64)
    opacities = torch.tensor([r[2] for r in rows], dtype=torch.float64)
    quats = torch.tensor([IDENTITY] * len(rows), dtype=torch.float64)
    return means, quats, scales, opacities


def _brute_force_visibility(means, quats, scales, opacities, light, w2c, K, g, mode, radius_px=2.0, offset=0.0):
    """Average over the pixels near g's projected centre of Π(1 - α_k(ray)) over the Gaussians in front.

    α_k(ray) = min(0.99, o_k · max_t G_k(light + t·dir)): the exact 3D maximum of Gaussian k along the shadow
    ray (closed form), independent of the splatting approximation under test.
    """
    m = means.numpy()
    cov = (quat_to_rotmat(quats) @ torch.diag_embed(scales**2) @ quat_to_rotmat(quats).transpose(-1, -2)).numpy()
    precision = np.linalg.inv(cov)
    light = light.numpy()
    w2c, K = w2c.double().numpy(), K.double().numpy()
    cam = w2c[:3, :3] @ m[g] + w2c[:3, 3]
    centre = (K @ cam)[:2] / cam[2]
    key = ((m - light) ** 2).sum(1)

    def peak(k, direction):  # max over t ≥ 0 of exp(-½ (t d - m)ᵀ A (t d - m)), m relative to the light
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
        ((0.0, 1.0, 0.08), 0.05, 0.9),  # 1 receiver behind it (slightly off the occluder's centre line)
        ((0.9, 1.0, 0.0), 0.05, 0.9),  # 2 receiver with nothing in front
        ((0.0, -5.0, 0.3), 0.05, 0.9),  # 3 behind the light: unseen
    ])  # fmt: skip


@pytest.mark.parametrize("mode", ["uniform", "density"])
def test_occluder_receiver_matches_brute_force_rays(mode):
    scene = _occluder_scene()
    result = shadow_gather(*scene, LIGHT, TARGET, resolution=128, backend="torch", mode=mode, scene_radius=1.5)
    w2c, K, _, _ = light_camera(LIGHT, TARGET, scene_radius=1.5, resolution=128)
    expected = _brute_force_visibility(*scene, LIGHT, w2c, K, g=1, mode=mode)
    assert 0.35 < expected < 0.75  # genuinely shadowed, by roughly 1 - α_occluder
    assert abs(float(result.visibility[1]) - expected) < 0.02
    assert float(result.visibility[0]) == pytest.approx(1.0, abs=1e-6)  # nothing in front of the occluder
    assert float(result.visibility[2]) == pytest.approx(1.0, abs=1e-6)
    assert result.seen.tolist() == [True, True, True, False]
    assert float(result.visibility[3]) == 0.0 and float(result.weight[3]) == 0.0


def test_hint_is_one_minus_occluder_alpha_on_the_centre_line():
    scene = _scene([((0.0, 0.0, 0.3), 0.3, 0.7), ((0.0, 1.0, 0.3), 0.05, 0.9)])  # both on one ray from the light
    result = shadow_gather(*scene, LIGHT, TARGET, resolution=128, backend="torch", scene_radius=1.5)
    assert float(result.visibility[1]) == pytest.approx(1 - 0.7, abs=0.03)


def test_depth_offset_excludes_near_coplanar_gaussians():
    # Two overlapping Gaussians whose squared distances to the light differ by ~0.03.
    scene = _scene([((0.0, 0.5, 0.3), 0.2, 0.8), ((0.0, 0.50332, 0.3), 0.2, 0.8)])
    plain = shadow_gather(*scene, LIGHT, TARGET, resolution=64, backend="torch", scene_radius=1.0)
    assert float(plain.visibility[1]) == pytest.approx(0.2, abs=0.03)
    offset = shadow_gather(*scene, LIGHT, TARGET, resolution=64, backend="torch", scene_radius=1.0, depth_offset=0.05)
    assert float(offset.visibility[1]) == pytest.approx(1.0, abs=1e-6)
    small = shadow_gather(*scene, LIGHT, TARGET, resolution=64, backend="torch", scene_radius=1.0, depth_offset=0.01)
    assert float(small.visibility[1]) == pytest.approx(0.2, abs=0.03)
    w2c, K, _, _ = light_camera(LIGHT, TARGET, scene_radius=1.0, resolution=64)
    for off in (0.0, 0.05):
        expected = _brute_force_visibility(*scene, LIGHT, w2c, K, g=1, mode="uniform", offset=off)
        got = shadow_gather(*scene, LIGHT, TARGET, resolution=64, backend="torch", scene_radius=1.0, depth_offset=off)
        assert abs(float(got.visibility[1]) - expected) < 0.02


def test_weight_of_a_lone_gaussian_is_its_splat_integral():
    scene = _scene([((0.0, 0.5, 0.0), 0.1, 0.5)])
    result = shadow_gather(*scene, LIGHT, TARGET, resolution=256, backend="torch", scene_radius=1.0)
    w2c, K, _, _ = light_camera(LIGHT, TARGET, scene_radius=1.0, resolution=256)
    depth = float((w2c[:3, :3].double() @ scene[0][0] + w2c[:3, 3].double())[2])
    sigma_px = 0.1 * float(K[0, 0]) / depth
    integral = 0.5 * 2 * math.pi * (sigma_px**2 + 0.3)  # o · ∫ G over the (low-pass widened) 2D Gaussian
    assert sigma_px > 5
    assert float(result.weight[0]) == pytest.approx(integral, rel=0.03)


def test_footprint_mode_averages_the_whole_splat():
    # A small occluder covers only the receiver's centre: the 2-px disc is darker than the whole footprint.
    scene = _scene([((0.0, 0.0, 0.3), 0.02, 0.95), ((0.0, 1.0, 0.3), 0.15, 0.9)])
    disc = shadow_gather(*scene, LIGHT, TARGET, resolution=128, backend="torch", scene_radius=1.2, mode="density")
    full = shadow_gather(*scene, LIGHT, TARGET, resolution=128, backend="torch", scene_radius=1.2, mode="footprint")
    assert float(disc.visibility[1]) < 0.5 < float(full.visibility[1]) < 1.0


def test_light_camera_fits_the_sphere_and_handles_parallel_up():
    light = torch.tensor([3.0, -2.0, 1.0])
    target = torch.tensor([0.2, 0.1, -0.1])
    w2c, K, width, _ = light_camera(light, target, scene_radius=0.8, resolution=100)
    rot = w2c[:3, :3].double()
    torch.testing.assert_close(rot @ rot.T, torch.eye(3, dtype=torch.float64), atol=1e-6, rtol=0)
    cam = rot @ target.double() + w2c[:3, 3].double()
    uv = (K.double() @ cam)[:2] / cam[2]
    torch.testing.assert_close(uv, torch.tensor([50.0, 50.0], dtype=torch.float64), atol=1e-4, rtol=0)
    # a point on the sphere's silhouette (tangent from the light) lands just inside the border
    distance = float((target - light).norm())
    half = math.asin(0.8 / distance)
    assert 0.5 * width / float(K[0, 0]) == pytest.approx(math.tan(half * 1.05), rel=1e-5)
    above = light_camera(torch.tensor([0.0, 0.0, 5.0]), torch.zeros(3), scene_radius=1.0)[0][:3, :3].double()
    torch.testing.assert_close(above @ above.T, torch.eye(3, dtype=torch.float64), atol=1e-6, rtol=0)
    assert float(above[2] @ torch.tensor([0.0, 0.0, -1.0], dtype=torch.float64)) == pytest.approx(1.0)
    fixed = light_camera(light, target, scene_radius=0.8, resolution=64, focal_px=80.0)[1]
    assert float(fixed[0, 0]) == 80.0 and float(fixed[1, 1]) == 80.0 and float(fixed[0, 2]) == 32.0
    inside = light_camera(torch.tensor([0.0, 0.0, 0.5]), torch.zeros(3), scene_radius=1.0, resolution=100)[1]
    assert 2 * math.degrees(math.atan(50 / float(K[0, 0]))) < 120.0
    assert 2 * math.degrees(math.atan(50 / float(inside[0, 0]))) == pytest.approx(120.0)


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
    assert torch.equal(ref.seen, cpp.seen) and bool(ref.seen.any()) and 0.05 < float(ref.visibility.mean()) < 0.95
    torch.testing.assert_close(ref.visibility, cpp.visibility, atol=2e-5, rtol=0)
    torch.testing.assert_close(ref.weight, cpp.weight, atol=1e-3, rtol=1e-4)
    # official options are torch-only: auto falls back, an explicit cpu request is refused
    assert shadow_gather(*args, resolution=32, **OFFICIAL_KERNEL).backend == "torch"
    with pytest.raises(ValueError, match="C\\+\\+ light pass implements"):
        shadow_gather(*args, resolution=32, backend="cpu", **OFFICIAL_KERNEL)


def test_bad_arguments():
    scene = _occluder_scene()
    with pytest.raises(ValueError, match="unknown shadow mode"):
        shadow_gather(*scene, LIGHT, TARGET, mode="paper")
    with pytest.raises(ValueError, match="coincides with the target"):
        shadow_gather(*scene, TARGET, TARGET)
