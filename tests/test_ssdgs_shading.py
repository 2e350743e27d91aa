"""SSD-GS shading terms against closed forms at hand-computed inputs."""

from __future__ import annotations

import math

import pytest
import torch

from olatbench.methods.shading.asg import ASGMixture
from olatbench.methods.shading.encoding import frequency_encoding, positional_encoding
from olatbench.methods.shading.terms import (
    inverse_square_irradiance,
    lambert_cosine,
    min_scale_frames,
    orient_frames,
    schlick_fresnel,
)
from olatbench.methods.ssdgs.sss import SSSNetwork, diffuse_reflectance_fresnel, dipole_profile


def t(*values: float) -> torch.Tensor:
    return torch.tensor([values], dtype=torch.float64)


def test_fresnel_normal_and_grazing_incidence() -> None:
    n = t(0, 0, 1)
    assert schlick_fresnel(n, n, f0=0.04).item() == pytest.approx(0.04)
    grazing_wi = t(1, 0, 0)
    half = t(0, 0, 1)  # ωi ⟂ h
    assert schlick_fresnel(grazing_wi, half, f0=0.04).item() == pytest.approx(1.0)
    # 60°: 0.04 + 0.96 · 0.5^5
    wi = t(math.sin(math.pi / 3), 0, math.cos(math.pi / 3))
    assert schlick_fresnel(wi, half).item() == pytest.approx(0.04 + 0.96 * 0.5**5)


def test_lambert_clamped_and_smooth() -> None:
    n = t(0, 0, 1)
    wi = t(0, math.sin(math.pi / 3), math.cos(math.pi / 3))
    assert lambert_cosine(n, wi, "clamped").item() == pytest.approx(0.5)
    assert lambert_cosine(n, -wi, "clamped").item() == 0.0
    # Smooth cosine: (ELU_0.01(c) + a(1-1/e)) / (1 + a(1-1/e)).
    offset = 0.01 * (1 - 1 / math.e)
    assert lambert_cosine(n, wi, "smooth").item() == pytest.approx((0.5 + offset) / (1 + offset))
    assert lambert_cosine(n, -n, "smooth").item() == pytest.approx(0.0, abs=1e-12)
    assert lambert_cosine(n, n, "smooth").item() == pytest.approx(1.0)
    back = lambert_cosine(n, -wi, "smooth").item()
    assert back == pytest.approx((0.01 * (math.exp(-0.5) - 1) + offset) / (1 + offset))
    with pytest.raises(ValueError, match="diffuse_cosine"):
        lambert_cosine(n, wi, "nope")  # type: ignore[arg-type]


def test_inverse_square_falloff() -> None:
    points = t(1, 2, 3)
    light = torch.tensor([1.0, 2.0, 5.0], dtype=torch.float64)
    wi, irradiance = inverse_square_irradiance(
        points, light, torch.tensor([2.0, 4.0, 8.0], dtype=torch.float64)
    )
    torch.testing.assert_close(wi, t(0, 0, 1))
    torch.testing.assert_close(irradiance, t(0.5, 1.0, 2.0))  # I / 2²


def test_min_scale_frame_is_right_handed_and_oriented() -> None:
    rot = torch.eye(3)[None].repeat(3, 1, 1)
    scales = torch.tensor([[0.1, 1.0, 1.0], [1.0, 0.1, 1.0], [1.0, 1.0, 0.1]])
    frames = min_scale_frames(rot, scales)
    for i in range(3):
        torch.testing.assert_close(frames[i, :, 2], torch.eye(3)[i])
        assert torch.linalg.det(frames[i]).item() == pytest.approx(1.0)
    wo = -torch.eye(3)  # cameras on the negative side of each normal
    oriented = orient_frames(frames, wo)
    for i in range(3):
        torch.testing.assert_close(oriented[i, :, 2], -torch.eye(3)[i])
        assert torch.linalg.det(oriented[i]).item() == pytest.approx(1.0)


def test_asg_xu_centre_and_off_axis() -> None:
    asg = ASGMixture(num_bases=2, form="xu").double()
    with torch.no_grad():
        asg.log_sharpness.copy_(
            torch.tensor([[math.log(4.0), math.log(9.0)], [math.log(1.0), math.log(1.0)]])
        )
    weights = torch.tensor([[1.0, 0.0]], dtype=torch.float64)
    assert asg(t(0, 0, 1), weights).item() == pytest.approx(1.0)  # lobe centre
    h = t(0.6, 0.0, 0.8)  # off-axis along x: 0.8 · exp(-4 · 0.36)
    assert asg(h, weights).item() == pytest.approx(0.8 * math.exp(-4 * 0.36))
    h = t(0.0, 0.6, 0.8)  # along y: 0.8 · exp(-9 · 0.36)
    assert asg(h, weights).item() == pytest.approx(0.8 * math.exp(-9 * 0.36))
    assert asg(t(0, 0, -1), weights).item() == 0.0  # smooth term max(h·z, 0)
    mixed = torch.tensor([[0.5, 2.0]], dtype=torch.float64)
    assert asg(h, mixed).item() == pytest.approx(
        0.5 * 0.8 * math.exp(-9 * 0.36) + 2.0 * 0.8 * math.exp(-0.36)
    )


def test_asg_official_form_closed_form() -> None:
    asg = ASGMixture(num_bases=1, form="official").double()
    lam, mu = (10 * torch.sigmoid(asg.raw_scales[0])).tolist()
    sigma = 0.5 * torch.nn.functional.softplus(torch.tensor(-2.0, dtype=torch.float64)).item()
    const = math.sqrt(2) * math.pi ** (2 / 3)
    one = torch.ones(1, 1, dtype=torch.float64)
    assert asg(t(0, 0, 1), one).item() == pytest.approx(1 / (const * sigma), rel=1e-4)
    theta = 0.2
    along_x = math.exp(-0.5 * (theta / lam / sigma) ** 2) / (const * sigma)
    along_y = math.exp(-0.5 * (theta / mu / sigma) ** 2) / (const * sigma)
    assert asg(t(math.sin(theta), 0, math.cos(theta)), one).item() == pytest.approx(
        along_x, rel=1e-4
    )
    assert asg(t(0, math.sin(theta), math.cos(theta)), one).item() == pytest.approx(
        along_y, rel=1e-4
    )


def test_dipole_hand_computed() -> None:
    eta, sigma_s, sigma_a, r = 1.3, 1.0, 0.5, 0.7
    f_dr = -1.440 / eta**2 + 0.710 / eta + 0.668 + 0.0636 * eta
    assert diffuse_reflectance_fresnel(eta) == pytest.approx(f_dr)
    a = (1 + f_dr) / (1 - f_dr)
    st = 1.5
    z_r = 1 / st
    z_v = z_r * (1 + 4 * a / 3)
    s_tr = math.sqrt(3 * sigma_a * st)
    d_r, d_v = math.hypot(r, z_r), math.hypot(r, z_v)
    real = z_r * (s_tr * d_r + 1) * math.exp(-s_tr * d_r) / d_r**3
    virt = (s_tr * d_v + 1) * math.exp(-s_tr * d_v) / d_v**3
    albedo = sigma_s / st
    args = (
        torch.tensor(r, dtype=torch.float64),
        torch.tensor(sigma_s, dtype=torch.float64),
        torch.tensor(sigma_a, dtype=torch.float64),
        eta,
    )
    jensen = dipole_profile(*args, virtual_factor="jensen").item()
    official = dipole_profile(*args, virtual_factor="official").item()
    assert jensen == pytest.approx(albedo / (4 * math.pi) * (real + z_v * virt))
    assert official == pytest.approx(albedo / (4 * math.pi) * (real + z_r * z_v * virt))
    # Worked out by hand: F_dr = 0.444763, A = 2.60206, z_v = 2.97961, σ_tr = 1.5, d_r = 0.966667,
    # d_v = 3.06074, real-source term 0.424147, virtual term 0.005889, α'/4π = 0.0530516.
    assert a == pytest.approx(2.60206, rel=1e-5)
    assert jensen == pytest.approx(0.0228143, rel=1e-4)


def test_sss_network_output_ranges() -> None:
    net = SSSNetwork(hidden=32)
    k = 64
    generator = torch.Generator().manual_seed(0)
    inputs = [torch.randn(k, 3, generator=generator) for _ in range(4)] + [
        torch.randn(k, 6, generator=generator)
    ]
    encoded = net.encode(*inputs)
    assert encoded.shape == (k, 3 * 27 + 3 + 6)
    sigma_s, sigma_a, r = net.parameters_from_input(encoded)
    for value, (lo, hi) in ((sigma_s, (0.05, 2.05)), (sigma_a, (0.05, 2.05)), (r, (0.1, 3.1))):
        assert bool(((value > lo) & (value < hi)).all())
    out = net(*inputs)
    assert out.shape == (k, 1) and bool((out > 0).all())


def test_encodings() -> None:
    x = t(0.25, -0.5, 1.0)
    pe = positional_encoding(x, 2)
    torch.testing.assert_close(pe[0, :3], x[0])
    torch.testing.assert_close(pe[0, 3:6], torch.sin(x[0]))
    torch.testing.assert_close(pe[0, 6:9], torch.sin(2 * x[0]))
    torch.testing.assert_close(pe[0, 9:12], torch.cos(x[0]))
    fe = frequency_encoding(x, 3)
    assert fe.shape == (1, 18)
    torch.testing.assert_close(fe[0, 3:6], torch.sin(2 * math.pi * x[0]))
    torch.testing.assert_close(fe[0, 9:12], torch.cos(math.pi * x[0]))


def test_sss_network_checkpointed_chunks_match_the_plain_batch(monkeypatch) -> None:
    """Large batches run Θ_SSS in checkpointed chunks (memory); values and every gradient are the
    plain path's."""
    from olatbench.methods.ssdgs import sss

    torch.manual_seed(0)
    net = SSSNetwork(material_dim=4, hidden=16, num_linear=4, num_freqs=2).double()
    k = 50
    inputs = [torch.randn(k, 3, dtype=torch.float64, requires_grad=True) for _ in range(4)]
    inputs.append(torch.randn(k, 4, dtype=torch.float64, requires_grad=True))

    def run() -> tuple[torch.Tensor, list[torch.Tensor]]:
        net.zero_grad(set_to_none=True)
        for tensor in inputs:
            tensor.grad = None
        out = net(*inputs)
        (out * torch.linspace(0.5, 1.5, k, dtype=torch.float64)[:, None]).sum().backward()
        return out.detach(), [t.grad.clone() for t in inputs] + [
            p.grad.clone() for p in net.parameters()
        ]

    plain_out, plain_grads = run()
    monkeypatch.setattr(sss, "CHECKPOINT_ROWS", 7)  # 50 rows -> 8 chunks
    calls = []
    real_checkpoint = sss.checkpoint
    monkeypatch.setattr(
        sss, "checkpoint", lambda *a, **kw: calls.append(1) or real_checkpoint(*a, **kw)
    )
    chunked_out, chunked_grads = run()
    assert len(calls) == 8
    torch.testing.assert_close(chunked_out, plain_out, rtol=1e-12, atol=1e-14)
    for chunked, plain in zip(chunked_grads, plain_grads, strict=True):
        torch.testing.assert_close(chunked, plain, rtol=1e-11, atol=1e-13)
