"""Pose and light refinement: identity at zero, exponential map, gradients vs finite differences."""

from __future__ import annotations

import math

import torch

from olatbench.gaussians.refinement import LightRefinement, PoseRefinement, so3_exp, so3xr3_exp


def _random_w2c(seed: int) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    q = torch.randn(4, generator=g, dtype=torch.float64)
    q /= q.norm()
    w, x, y, z = q
    rot = torch.tensor(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ],
        dtype=torch.float64,
    )
    w2c = torch.eye(4, dtype=torch.float64)
    w2c[:3, :3], w2c[:3, 3] = rot, torch.randn(3, generator=g, dtype=torch.float64)
    return w2c


def test_zero_refinement_is_identity():
    poses = PoseRefinement(5)
    w2c = _random_w2c(0).float()
    assert torch.equal(poses.apply(3, w2c), w2c)
    assert torch.equal(poses.delta(torch.tensor([0, 4])), torch.eye(4).expand(2, 4, 4))
    lights = LightRefinement(4)
    position = torch.tensor([1.0, -2.0, 3.0])
    assert torch.equal(lights.apply(2, position), position)


def test_so3_exp_matches_axis_angle_closed_form():
    axis = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)
    rot = so3_exp(axis * (math.pi / 2))
    expected = torch.tensor([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]], dtype=torch.float64)
    torch.testing.assert_close(rot, expected, atol=1e-12, rtol=0)
    omega = torch.randn(10, 3, dtype=torch.float64) * 2
    r = so3_exp(omega)
    torch.testing.assert_close(
        r @ r.transpose(-1, -2), torch.eye(3, dtype=torch.float64).expand(10, 3, 3)
    )
    torch.testing.assert_close(torch.linalg.det(r), torch.ones(10, dtype=torch.float64))
    # rotation axis is fixed, and the matrix exponential agrees
    torch.testing.assert_close((r @ omega[..., None]).squeeze(-1), omega)
    hat = torch.zeros(10, 3, 3, dtype=torch.float64)
    hat[:, 0, 1], hat[:, 0, 2], hat[:, 1, 2] = -omega[:, 2], omega[:, 1], -omega[:, 0]
    hat = hat - hat.transpose(-1, -2)
    torch.testing.assert_close(r, torch.linalg.matrix_exp(hat))


def test_translation_is_not_coupled_to_rotation():
    xi = torch.tensor([0.1, 0.2, 0.3, 0.5, -0.4, 0.2], dtype=torch.float64)
    delta = so3xr3_exp(xi)
    torch.testing.assert_close(delta[:3, 3], xi[:3])
    torch.testing.assert_close(delta[3], torch.tensor([0.0, 0, 0, 1], dtype=torch.float64))


def test_pose_gradient_matches_finite_differences_at_zero_and_away():
    w2c = _random_w2c(1)
    point = torch.tensor([0.3, -0.2, 2.0, 1.0], dtype=torch.float64)

    def camera_point(tangent: torch.Tensor) -> torch.Tensor:
        poses = PoseRefinement(1, dtype=torch.float64)
        with torch.no_grad():
            poses.tangents.copy_(tangent[None])
        return poses, poses.apply(0, w2c) @ point

    for tangent in (
        torch.zeros(6, dtype=torch.float64),
        torch.tensor([0.1, -0.3, 0.2, 0.4, -0.7, 0.25]).double(),
    ):
        poses, out = camera_point(tangent)
        (out[:3] ** 2).sum().backward()
        analytic = poses.tangents.grad[0]
        numeric = torch.zeros(6, dtype=torch.float64)
        eps = 1e-6
        for i in range(6):
            step = torch.zeros(6, dtype=torch.float64)
            step[i] = eps
            plus = (camera_point(tangent + step)[1][:3] ** 2).sum()
            minus = (camera_point(tangent - step)[1][:3] ** 2).sum()
            numeric[i] = (plus - minus) / (2 * eps)
        torch.testing.assert_close(analytic, numeric, rtol=1e-6, atol=1e-8)


def test_gradcheck_near_zero_angle():
    omega = torch.tensor([1e-6, -2e-6, 5e-7], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(so3_exp, (omega,))
    zero = torch.zeros(3, dtype=torch.float64, requires_grad=True)
    so3_exp(zero).sum().backward()
    assert torch.isfinite(zero.grad).all()


def test_light_refinement_gradient():
    lights = LightRefinement(3)
    target = torch.tensor([1.0, 2.0, 3.0])
    loss = ((lights.apply(1, torch.zeros(3)) - target) ** 2).sum()
    loss.backward()
    torch.testing.assert_close(lights.offsets.grad[1], -2 * target)
    assert torch.equal(lights.offsets.grad[0], torch.zeros(3))
