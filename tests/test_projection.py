"""EWA projection: closed forms, an autograd Jacobian of the pinhole map, culling, and finite
differences."""

from __future__ import annotations

import math

import pytest
import torch
from test_rasterize_scenes import camera, scene

from olatbench.gaussians.projection import covariances_3d, project, quat_to_rotmat

D = torch.float64


def hamilton(p: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
    pw, px, py, pz = p.unbind(-1)
    qw, qx, qy, qz = q.unbind(-1)
    return torch.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        dim=-1,
    )


def test_rotation_matches_quaternion_sandwich():
    g = torch.Generator().manual_seed(3)
    q = torch.randn(8, 4, generator=g, dtype=D) * 2.5
    v = torch.randn(8, 3, generator=g, dtype=D)
    qn = q / q.norm(dim=-1, keepdim=True)
    conj = qn * torch.tensor([1.0, -1.0, -1.0, -1.0], dtype=D)
    rotated = hamilton(hamilton(qn, torch.cat([torch.zeros(8, 1, dtype=D), v], -1)), conj)[:, 1:]
    R = quat_to_rotmat(q)
    torch.testing.assert_close((R @ v[:, :, None])[..., 0], rotated)
    torch.testing.assert_close(torch.linalg.det(R), torch.ones(8, dtype=D))


def test_isotropic_gaussian_closed_form():
    fx, fy, cx, cy, s = 50.0, 60.0, 20.0, 15.0, 0.1
    K = torch.tensor([[fx, 0, cx], [0, fy, cy], [0, 0, 1]], dtype=D)
    x, y, z = 0.2, -0.1, 2.0
    p = project(
        torch.tensor([[x, y, z]], dtype=D),
        torch.tensor([[1.0, 0, 0, 0]], dtype=D),
        torch.full((1, 3), s, dtype=D),
        torch.eye(4, dtype=D),
        K,
        40,
        30,
    )
    torch.testing.assert_close(
        p.means2d[0], torch.tensor([fx * x / z + cx, fy * y / z + cy], dtype=D)
    )
    # J Jᵀ s² for the pinhole Jacobian, plus the 0.3 px² low-pass.
    a = s * s * fx * fx / z**2 * (1 + x * x / z**2) + 0.3
    c = s * s * fy * fy / z**2 * (1 + y * y / z**2) + 0.3
    b = s * s * fx * fy * x * y / z**4
    det = a * c - b * b
    torch.testing.assert_close(p.conics[0], torch.tensor([c / det, -b / det, a / det], dtype=D))
    lam = 0.5 * (a + c) + math.sqrt(0.25 * (a - c) ** 2 + b * b)
    assert int(p.radii[0]) == math.ceil(3 * math.sqrt(lam))
    assert float(p.depths[0]) == pytest.approx(z)


def test_covariance_matches_autograd_jacobian_of_pinhole():
    """Inside the frustum (no clamping) the 2D covariance is Jπ W Σ Wᵀ Jπᵀ + 0.3 I with Jπ from
    autograd."""
    W, H = 64, 48
    w2c, K = camera(W, H)
    s = scene(10, spread=0.4)
    p = project(s["means"], s["quats"], s["scales"], w2c, K, W, H)

    def pinhole(x: torch.Tensor) -> torch.Tensor:
        cam = w2c[:3, :3] @ x + w2c[:3, 3]
        return (K @ cam)[:2] / cam[2]

    for i in range(10):
        jac = torch.autograd.functional.jacobian(pinhole, s["means"][i])
        sigma = covariances_3d(s["quats"][i : i + 1], s["scales"][i : i + 1])[0]
        cov = jac @ sigma @ jac.T + 0.3 * torch.eye(2, dtype=D)
        inv = torch.linalg.inv(cov)
        torch.testing.assert_close(p.conics[i], torch.stack([inv[0, 0], inv[0, 1], inv[1, 1]]))
        torch.testing.assert_close(p.means2d[i], pinhole(s["means"][i]))
        assert int(p.radii[i]) == math.ceil(3 * math.sqrt(float(torch.linalg.eigvalsh(cov).max())))


def test_jacobian_clamped_outside_frustum():
    """Far off-axis Gaussians use x/z clamped to 1.3 × the half-FoV tangent
    (centred principal point)."""
    W, H, f = 40, 40, 40.0
    K = torch.tensor([[f, 0, W / 2], [0, f, H / 2], [0, 0, 1]], dtype=D)
    z, s = 2.0, 2.0
    # x/z = 3, far beyond 1.3 × tan(fov/2) = 0.65; the huge Gaussian still reaches the image
    x = 3.0 * z
    p = project(
        torch.tensor([[x, 0.0, z]], dtype=D),
        torch.tensor([[1.0, 0, 0, 0]], dtype=D),
        torch.full((1, 3), s, dtype=D),
        torch.eye(4, dtype=D),
        K,
        W,
        H,
    )
    u = 1.3 * 0.5 * W / f
    a = s * s * f * f / z**2 * (1 + u * u) + 0.3
    c = s * s * f * f / z**2 + 0.3
    torch.testing.assert_close(p.conics[0], torch.tensor([1 / a, 0.0, 1 / c], dtype=D))
    assert int(p.radii[0]) > 0


def test_culling_and_finite_gradients():
    W, H = 32, 32
    K = torch.tensor([[30.0, 0, 16], [0, 30.0, 16], [0, 0, 1]], dtype=D)
    means = torch.tensor(
        [
            [0.0, 0.0, 2.0],
            [0.0, 0.0, -2.0],
            [0.0, 0.0, 0.005],
            [0.0, 0.0, 1e11],
            [50.0, 0.0, 2.0],
            [0.0, 0, 0],
        ],
        dtype=D,
        requires_grad=True,
    )
    n = means.shape[0]
    quats = torch.tensor([[1.0, 0, 0, 0]] * n, dtype=D, requires_grad=True)
    scales = torch.full((n, 3), 0.05, dtype=D)
    # degenerate: still a valid (low-pass) 2D Gaussian, but behind the near plane here
    scales[-1] = 1e-12
    scales.requires_grad_()
    p = project(means, quats, scales, torch.eye(4, dtype=D), K, W, H)
    # behind, too near, too far, off-screen, at z = 0
    assert p.radii[0] > 0 and (p.radii[1:] == 0).all()
    assert torch.isfinite(p.means2d).all() and torch.isfinite(p.conics).all()
    (p.means2d.sum() + p.conics.sum() + p.depths.sum()).backward()
    for t in (means, quats, scales):
        assert torch.isfinite(t.grad).all()


def test_degenerate_scale_gives_low_pass_footprint():
    K = torch.tensor([[30.0, 0, 16], [0, 30.0, 16], [0, 0, 1]], dtype=D)
    p = project(
        torch.tensor([[0.0, 0.0, 2.0]], dtype=D), torch.tensor([[0.3, 0.1, 0, 0.2]], dtype=D),
        torch.full((1, 3), 1e-12, dtype=D), torch.eye(4, dtype=D), K, 32, 32,
    )  # fmt: skip
    torch.testing.assert_close(p.conics[0], torch.tensor([1 / 0.3, 0.0, 1 / 0.3], dtype=D))
    assert int(p.radii[0]) == math.ceil(3 * math.sqrt(0.3))


def test_unnormalised_quaternions_are_normalised():
    W, H = 40, 30
    w2c, K = camera(W, H)
    s = scene(7)
    p1 = project(s["means"], s["quats"], s["scales"], w2c, K, W, H)
    p2 = project(s["means"], s["quats"] * 3.7, s["scales"], w2c, K, W, H)
    torch.testing.assert_close(p1.conics, p2.conics)
    assert torch.equal(p1.radii, p2.radii)


def test_projection_gradients_match_finite_differences():
    """Central finite differences (float64) for means, quats, scales and the camera pose."""
    W, H = 40, 30
    w2c, K = camera(W, H)
    s = scene(5, spread=0.6)
    s["means"][0, 0] = 4.0  # one Gaussian outside the frustum: exercises the clamped Jacobian
    g = torch.Generator().manual_seed(7)
    weights = [torch.randn(5, k, generator=g, dtype=D) for k in (2, 3, 1)]

    def f(means, quats, scales, pose):
        p = project(means, quats, scales, pose, K, W, H)
        outs = (p.means2d, p.conics, p.depths[:, None])
        return sum((o * w).sum() for o, w in zip(outs, weights, strict=True))

    inputs = [s["means"], s["quats"], s["scales"], w2c]
    assert torch.autograd.gradcheck(
        f, [t.clone().requires_grad_() for t in inputs], eps=1e-6, atol=1e-7, rtol=1e-5
    )
