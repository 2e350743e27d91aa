"""C++ SSIM training loss against the torch reference: values, gradients, determinism and backend
dispatch."""

from __future__ import annotations

import warnings

import pytest
import torch

from olatbench import _native
from olatbench.methods.training import photometric_loss
from olatbench.metrics.ssim import resolve_ssim_backend, ssim_loss
from olatbench.metrics.ssim_cpu import LIBRARY, ssim_loss_cpu

_STATUS = LIBRARY.status()
pytestmark = pytest.mark.skipif(not _STATUS[0], reason=f"C++ SSIM kernel unavailable: {_STATUS[1]}")


def images(shape, dtype=torch.float64, seed=0, noise=0.15):
    """A random prediction and a noisy, clamped target of the same shape."""
    g = torch.Generator().manual_seed(seed)
    pred = torch.rand(shape, generator=g, dtype=torch.float64)
    gt = (pred + noise * torch.randn(shape, generator=g, dtype=torch.float64)).clamp(0, 1)
    return pred.to(dtype), gt.to(dtype)


def loss_and_grad(pred, gt, **kwargs):
    leaf = pred.clone().requires_grad_(True)
    loss = ssim_loss(leaf, gt, **kwargs)
    loss.backward()
    return loss.detach(), leaf.grad, type(loss.grad_fn).__name__


def assert_grad_close(grad, ref, rel):
    assert grad.shape == ref.shape
    assert float((grad - ref).abs().max()) <= rel * float(ref.abs().max())


@pytest.mark.parametrize("size", [(11, 11), (17, 23), (64, 48)])
@pytest.mark.parametrize("channels", [1, 3])
@pytest.mark.parametrize("channels_last", [False, True])
def test_float64_matches_torch_reference(size, channels, channels_last):
    shape = (2, *size, channels) if channels_last else (2, channels, *size)
    pred, gt = images(shape, seed=size[0] * channels)
    loss, grad, node = loss_and_grad(pred, gt, channels_last=channels_last)
    ref, ref_grad, ref_node = loss_and_grad(pred, gt, channels_last=channels_last, backend="torch")
    assert "SSIMLossCPU" in node and "SSIMLossCPU" not in ref_node  # "auto" took the C++ kernel
    assert float(loss) == pytest.approx(float(ref), rel=1e-12, abs=0)
    with torch.no_grad():  # the forward without saved derivatives gives the same value
        assert torch.equal(ssim_loss(pred, gt, channels_last=channels_last, backend="cpu"), loss)
    assert_grad_close(grad, ref_grad, 1e-10)


def test_any_memory_layout_matches_torch_reference():
    base, gt = images((2, 3, 26, 42), seed=8)
    layouts = {  # (view of the leaf given to ssim_loss, gt)
        "strided slice": (lambda t: t[..., ::2], gt[..., ::2]),
        "transposed": (lambda t: t.transpose(-1, -2).contiguous().transpose(-1, -2), gt),
        "channels-last": (lambda t: t.contiguous(memory_format=torch.channels_last), gt),
        "broadcast gt": (lambda t: t, gt[:1].expand(2, -1, -1, -1)),
        "channels-last gt": (lambda t: t, gt.contiguous(memory_format=torch.channels_last)),
    }
    for name, (view, target) in layouts.items():
        results = []
        for backend in ("cpu", "torch"):
            leaf = base.clone().requires_grad_(True)
            loss = ssim_loss(view(leaf), target, backend=backend)
            loss.backward()
            results.append((float(loss.detach()), leaf.grad))
        (loss, grad), (ref, ref_grad) = results
        assert loss == pytest.approx(ref, rel=1e-12, abs=0), name
        assert_grad_close(grad, ref_grad, 1e-10)


def test_unbatched_training_call_uses_the_kernel_and_matches():
    image, target = images((40, 56, 3), dtype=torch.float32, seed=3)
    leaf = image.clone().requires_grad_(True)
    loss, _ = photometric_loss(leaf, target, 0.2)
    loss.backward()
    ref_leaf = image.clone().requires_grad_(True)
    ref = 0.8 * (ref_leaf - target).abs().mean() + 0.2 * ssim_loss(
        ref_leaf, target, channels_last=True, backend="torch"
    )
    ref.backward()
    assert resolve_ssim_backend(image.movedim(-1, 0)[None], target.movedim(-1, 0)[None]) == "cpu"
    assert float(loss.detach()) == pytest.approx(float(ref.detach()), abs=1e-6)
    assert_grad_close(leaf.grad, ref_leaf.grad, 1e-4)


def test_gradcheck_float64():
    pred, gt = images((1, 2, 12, 13), seed=5)
    pred.requires_grad_(True)
    assert torch.autograd.gradcheck(
        lambda p: ssim_loss_cpu(p, gt), (pred,), eps=1e-6, atol=1e-9, rtol=1e-5
    )


@pytest.mark.parametrize("shape", [(1, 3, 128, 128), (2, 1, 33, 70)])
def test_float32_matches_torch_float32_reference(shape):
    pred, gt = images(shape, dtype=torch.float32, seed=shape[-1])
    loss, grad, node = loss_and_grad(pred, gt)
    ref, ref_grad, _ = loss_and_grad(pred, gt, backend="torch")
    assert "SSIMLossCPU" in node and loss.dtype == grad.dtype == torch.float32
    assert float(loss) == pytest.approx(float(ref), abs=1e-5)
    assert_grad_close(grad, ref_grad, 1e-4)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_result_does_not_depend_on_the_thread_count(dtype):
    pred, gt = images((2, 3, 37, 29), dtype=dtype, seed=11)
    results = []
    for threads in (1, 2, 3):
        leaf = pred.clone().requires_grad_(True)
        loss = ssim_loss_cpu(leaf, gt, threads=threads)
        loss.backward()
        results.append((loss.detach(), leaf.grad))
    for loss, grad in results[1:]:
        assert torch.equal(loss, results[0][0]) and torch.equal(grad, results[0][1])


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_identical_images_give_zero_loss_and_gradient(dtype):
    pred, _ = images((1, 3, 24, 31), dtype=dtype, seed=2)
    loss, grad, node = loss_and_grad(pred, pred.clone())
    ref, ref_grad, _ = loss_and_grad(pred, pred.clone(), backend="torch")
    assert "SSIMLossCPU" in node
    assert abs(float(loss)) < 1e-6 and abs(float(loss) - float(ref)) < 1e-6
    assert float(grad.abs().max()) < 1e-6 and float((grad - ref_grad).abs().max()) < 1e-6


def test_auto_uses_torch_when_the_kernel_does_not_apply():
    pred, gt = images((1, 3, 20, 24), seed=4)
    target = gt.clone().requires_grad_(True)  # the kernel has no gradient for gt
    leaf = pred.clone().requires_grad_(True)
    ssim_loss(leaf, target).backward()
    assert target.grad is not None and float(target.grad.abs().max()) > 0
    cases = {
        "gt requires grad": (pred, target, "3dgs"),
        "wang variant": (pred, gt, "wang"),
        "meta device": (pred.to("meta"), gt.to("meta"), "3dgs"),
        "half precision": (pred.half(), gt.half(), "3dgs"),
        "mixed dtypes": (pred, gt.float(), "3dgs"),
    }
    for name, (p, g, variant) in cases.items():
        assert resolve_ssim_backend(p, g, variant) == "torch", name
        with pytest.raises(ValueError, match="SSIM backend 'cpu' cannot"):
            resolve_ssim_backend(p, g, variant, backend="cpu")
        with pytest.raises(ValueError, match="SSIM backend 'cpu' cannot"):
            ssim_loss(p, g, variant, backend="cpu")
    meta = ssim_loss(pred.to("meta"), gt.to("meta"))
    assert meta.device.type == "meta" and meta.shape == ()
    with torch.no_grad():
        # no graph: gt's requires_grad does not matter
        assert resolve_ssim_backend(pred, target) == "cpu"
    with pytest.raises(ValueError, match="at least 11"):
        ssim_loss(pred[..., :10, :], gt[..., :10, :])
    with pytest.raises(ValueError, match=r"SSIM backend 'cpu' cannot.*at least 11"):
        ssim_loss(pred[..., :10, :], gt[..., :10, :], backend="cpu")
    with pytest.raises(ValueError, match="unknown SSIM backend"):
        ssim_loss(pred, gt, backend="cuda")
    with pytest.raises(ValueError, match="ssim_loss_cpu: it has no gradient for gt"):
        ssim_loss_cpu(pred, target)


@pytest.fixture
def broken_build(monkeypatch, tmp_path):
    """An empty build cache, a compiler that does not exist, and no remembered build outcome or
    warning."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setenv("OLATBENCH_CXX", str(tmp_path / "no-such-compiler"))
    _native.reset_fallback_warnings()
    LIBRARY.reset()
    yield
    LIBRARY.reset()
    _native.reset_fallback_warnings()


def test_failed_build_falls_back_to_torch_with_one_warning(broken_build):
    pred, gt = images((1, 3, 16, 16), seed=6)
    with pytest.warns(
        RuntimeWarning, match=r"SSIM backend 'cpu' is unavailable, falling back.*no-such-compiler"
    ):
        assert resolve_ssim_backend(pred, gt) == "torch"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        loss = ssim_loss(pred, gt)  # only one warning per process
    assert float(loss) == pytest.approx(float(ssim_loss(pred, gt, backend="torch")), rel=1e-15)
    with pytest.raises(RuntimeError, match="no-such-compiler"):
        # an explicit request fails loudly instead of falling back
        ssim_loss(pred, gt, backend="cpu")
