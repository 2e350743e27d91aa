"""Reduced-precision per-Gaussian networks: autocast only inside the networks, gradients close to
float32, clear refusals where the hardware lacks fast bf16 / fp16, and fp16 loss scaling."""

from __future__ import annotations

import pytest
import torch
from ssdgs_scenes import sphere_views

from olatbench.methods.baselines.gs3_shading import OtherEffectsNetwork
from olatbench.methods.shading import precision
from olatbench.methods.shading.precision import (
    LossScaler,
    check_precision,
    fast_bf16_cpu_flag,
    run_network,
)
from olatbench.methods.shading.shadow_mlp import ShadowNetwork
from olatbench.methods.ssdgs import SSDGS
from olatbench.methods.ssdgs.sss import SSSNetwork

SMALL = {
    "iterations": 1_000,
    "reference_iterations": 100_000,
    "num_init_gaussians": 300,
    "init_radius": 1.3,
    "max_gaussians": 3_000,
    "shadow_resolution": 24,
    "sss_hidden": 32,
    "num_asg": 4,
    "densify_from": 10_000,
    "densify_until": 60_000,
    "opacity_reset_interval": 100_000,
}


def _inputs(k: int, seed: int = 0) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    unit = lambda: torch.nn.functional.normalize(torch.randn(k, 3, generator=g), dim=-1)  # noqa: E731
    return {
        "positions": torch.rand(k, 3, generator=g) * 2 - 1,
        "wo": unit(),
        "wi": unit(),
        "normals": unit(),
        "material": torch.randn(k, 6, generator=g),
        "coarse": torch.rand(k, 1, generator=g),
    }


def _networks(precision_name: str) -> dict[str, tuple[torch.nn.Module, callable]]:
    """Each network at ``precision_name`` with seed-0 weights, and a call on the shared inputs."""
    torch.manual_seed(0)
    sss = SSSNetwork(hidden=64, precision=precision_name)
    shadow = ShadowNetwork(precision=precision_name)
    other = OtherEffectsNetwork(precision=precision_name)
    return {
        "sss": (sss, lambda x: sss(x["positions"], x["wo"], x["wi"], x["normals"], x["material"])),
        "shadow": (shadow, lambda x: shadow(x["positions"], x["wi"], x["coarse"], x["material"])),
        "other": (other, lambda x: other(x["wo"], x["positions"], x["material"])),
    }


def _output_and_gradients(module, call, inputs):
    inputs = {name: t.clone().requires_grad_(True) for name, t in inputs.items()}
    out = call(inputs)
    weights = torch.randn(out.shape, generator=torch.Generator().manual_seed(1))
    (out * weights).sum().backward()
    grads = [p.grad.clone() for p in module.parameters()] + [inputs["positions"].grad.clone()]
    return out.detach(), grads


def _relative_error(a: torch.Tensor, b: torch.Tensor) -> float:
    return float((a - b).norm() / b.norm().clamp_min(1e-30))


class _RoundToBF16(torch.autograd.Function):
    """Identity that rounds its value (forward) and its gradient (backward) to bf16, in float32
    tensors."""

    @staticmethod
    def forward(ctx, x):
        return x.bfloat16().float()

    @staticmethod
    def backward(ctx, grad):
        return grad.bfloat16().float()


def _emulated_bf16_linear(self, x):
    """A Linear as autocast runs it at bf16, emulated in float32: operands and result rounded to
    bf16, and so is every gradient through them (float32 accumulation in between)."""
    r = _RoundToBF16.apply
    return r(
        torch.nn.functional.linear(
            r(x), r(self.weight), None if self.bias is None else r(self.bias)
        )
    )


@pytest.mark.parametrize("name", ["sss", "shadow", "other"])
def test_bf16_outputs_and_gradients_match_an_emulated_bf16_reference(name, monkeypatch):
    inputs = _inputs(512)
    module32, call32 = _networks("fp32")[name]
    module16, call16 = _networks("bf16")[name]
    linear_dtypes = []
    for layer in module16.modules():
        if isinstance(layer, torch.nn.Linear):
            layer.register_forward_hook(lambda _m, _i, out: linear_dtypes.append(out.dtype))
    out32, grads32 = _output_and_gradients(module32, call32, inputs)
    out16, grads16 = _output_and_gradients(module16, call16, inputs)
    assert set(linear_dtypes) == {torch.bfloat16}  # every layer really ran in bf16...
    # ...and nothing else
    assert out16.dtype == torch.float32 and all(g.dtype == torch.float32 for g in grads16)
    module_ref, call_ref = _networks("fp32")[name]
    monkeypatch.setattr(torch.nn.Linear, "forward", _emulated_bf16_linear)
    out_ref, grads_ref = _output_and_gradients(module_ref, call_ref, inputs)
    monkeypatch.undo()
    # the autocast path computes what bf16 rounding of the Linear layers gives
    # (up to accumulation order)...
    assert _relative_error(out16, out_ref) < 1e-3
    for g16, g_ref in zip(grads16, grads_ref, strict=True):
        assert _relative_error(g16, g_ref) < 5e-3
    # ...which is float32's output within 2 % and its gradients within bf16's tolerance (8 mantissa
    # bits, 0.4 % per rounding, compounded over the layers and the cancelling sums of 512 rows: 1-18
    # % here)
    assert 0 < _relative_error(out16, out32) < 2e-2
    for g16, g32 in zip(grads16, grads32, strict=True):
        assert _relative_error(g16, g32) < 0.25
        assert (
            float(torch.nn.functional.cosine_similarity(g16.flatten(), g32.flatten(), dim=0)) > 0.97
        )


def test_fp32_runs_without_autocast():
    seen = []
    layer = torch.nn.Linear(4, 4)
    layer.register_forward_hook(
        lambda _m, _i, out: seen.append((out.dtype, torch.is_autocast_enabled("cpu")))
    )
    run_network(layer, torch.randn(3, 4), "fp32")
    assert seen == [(torch.float32, False)]


def test_bf16_needs_amx_or_avx512_bf16_on_the_cpu(monkeypatch):
    monkeypatch.setattr(precision, "cpu_flags", lambda: ["avx2", "avx512f"])
    assert fast_bf16_cpu_flag() is None
    with pytest.raises(
        ValueError,
        match=r"SSD-GS: network_precision='bf16' is not supported here: this CPU has "
        r"neither AMX \(amx_tile\) nor AVX512-BF16.*Use network_precision=fp32",
    ):
        check_precision("bf16", "cpu", "SSD-GS")
    method = SSDGS(SSDGS.resolve_config(None, **SMALL, network_precision="bf16"))
    with pytest.raises(ValueError, match="network_precision='bf16' is not supported here"):
        method.setup(sphere_views(2, size=16), "cpu", 0)
    for flags, expected in (
        (["avx512_bf16"], "avx512_bf16"),
        (["amx_tile", "avx512_bf16"], "amx_tile"),
    ):
        monkeypatch.setattr(precision, "cpu_flags", lambda flags=flags: flags)
        assert fast_bf16_cpu_flag() == expected
        check_precision("bf16", "cpu", "SSD-GS")  # accepted
    with pytest.raises(ValueError, match="fp16 runs on CUDA only"):
        check_precision("fp16", "cpu", "GS³")
    with pytest.raises(ValueError, match="network_precision must be one of"):
        SSDGS.resolve_config(None, network_precision="int8")


def test_loss_scaler_skips_and_halves_on_overflow_and_grows_after_an_interval():
    scaler = LossScaler(initial=8.0, growth_interval=2)
    grads = [torch.tensor([8.0, 16.0]), None]
    assert scaler.unscale(grads) and torch.equal(grads[0], torch.tensor([1.0, 2.0]))
    assert not scaler.unscale([torch.tensor([float("inf")])])
    scaler.update(False)
    assert scaler.scale == 4.0
    scaler.update(True)
    scaler.update(True)
    assert scaler.scale == 8.0 and scaler.finite_steps == 0


@pytest.fixture
def fp16_on_cpu(monkeypatch):
    """Let fp16 run on the CPU (refused there in use: no fast fp16) to exercise the loss-scaling
    step."""
    monkeypatch.setattr(precision, "precision_unsupported", lambda *_: None)


def test_fp16_training_step_unscales_every_gradient(fp16_on_cpu):
    views = sphere_views(2, size=16)
    fp16 = SSDGS(SSDGS.resolve_config(None, **SMALL, network_precision="fp16"))
    fp16.setup(views, "cpu", 0)
    assert fp16.loss_scaler is not None and fp16.loss_scaler.scale == 2.0**16
    # same seed, scaling removed
    plain = SSDGS(SSDGS.resolve_config(None, **SMALL, network_precision="fp16"))
    plain.setup(views, "cpu", 0)
    plain.loss_scaler = None
    step = 30_000  # every term on
    scaled = fp16.compute_gradients(step, index=0)
    assert fp16._unscale_gradients(scaled["projected"].means2d.grad)
    reference = plain.compute_gradients(step, index=0)
    # Gaussian-parameter and 2D-mean gradients are back at their unscaled size
    # (fp16 rounding differs)
    fp16_params, plain_params = (
        fp16.model.per_gaussian_parameters(),
        plain.model.per_gaussian_parameters(),
    )
    for name in ("means", "attributes.diffuse", "attributes.material"):
        assert _relative_error(fp16_params[name].grad, plain_params[name].grad) < 5e-2, name
    assert (
        _relative_error(scaled["projected"].means2d.grad, reference["projected"].means2d.grad)
        < 5e-2
    )
    # an overflow skips the whole update and halves the scale
    fp16.loss_scaler.scale = 1e38
    before = fp16.model.means.detach().clone()
    result = fp16.train_step(step)
    assert result["skipped"] == 1.0 and fp16.loss_scaler.scale == 5e37
    assert torch.equal(fp16.model.means, before) and fp16.step == step + 1
    state = fp16.state_dict()
    assert state["loss_scaler"]["scale"] == 5e37


def test_backends_record_the_network_precision(monkeypatch):
    monkeypatch.setattr(precision, "cpu_flags", lambda: ["avx512_bf16"])
    method = SSDGS(SSDGS.resolve_config(None, **SMALL, network_precision="bf16"))
    method.setup(sphere_views(2, size=16), "cpu", 0)
    assert method.backends()["network_precision"] == "bf16"
    assert method.shader.sss_net.precision == method.shader.shadow_net.precision == "bf16"
