"""C++ forward and backward of the "3dgs" SSIM training loss (``metrics/csrc/ssim.cpp``), called
through ctypes.

Computes ``ssim_loss(pred, gt, variant="3dgs")`` of ``olatbench.metrics.ssim`` (11-tap Gaussian
window, σ = 1.5, zero padding of 5 px, mean over every pixel and channel; the same value up to
rounding) for CPU float32/float64 (B, C, H, W) tensors of any strides (NCHW, and channels-last views
such as ``movedim(-1, -3)`` of (H, W, C) images, are read in place), with a hand-written backward
for ``pred`` only (``gt`` is a constant target). The kernel is the metrics layer's own native
library, ``LIBRARY`` (built on first use by ``olatbench._native``), and gives the same result for
any thread count. ``ssim.ssim_loss`` dispatches here by default (and leaves images smaller than
11×11, which this kernel would accept, to the torch code's error); call it rather than this module.
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import torch
from torch.autograd.function import once_differentiable

from olatbench._native import NativeLibrary, Signature, per_float
from olatbench._native.tensors import FLOAT_SUFFIXES, float_suffix, pointer, thread_count

_DERIVATIVES = 3  # per-pixel maps saved for the backward: dSSIM/dmu_p, dSSIM/dE_pp, dSSIM/dE_pg
# _STRIDES: int64_t[4]
_P, _I64, _STRIDES = ctypes.c_void_p, ctypes.c_int64, ctypes.POINTER(ctypes.c_int64)
_SIZES = (_I64, _I64, _I64, _I64)  # batch, channels, height, width


def _symbols(suffix: str, real: type) -> dict[str, Signature]:
    """The exported functions of ``csrc/ssim.cpp`` for one float type
    (its ``OLATBENCH_SSIM_DEFINE``)."""
    return {
        # pred, pred strides, gt, gt strides, sizes, threads -> derivatives (or NULL), sum of the
        # SSIM map
        f"olatbench_ssim_loss_forward_{suffix}": Signature(
            None,
            (
                _P,
                _STRIDES,
                _P,
                _STRIDES,
                *_SIZES,
                ctypes.c_int,
                _P,
                ctypes.POINTER(ctypes.c_double),
            ),
        ),
        # pred, pred strides, gt, gt strides, derivatives, sizes, threads, grad scale -> grad pred
        f"olatbench_ssim_loss_backward_{suffix}": Signature(
            None, (_P, _STRIDES, _P, _STRIDES, _P, *_SIZES, ctypes.c_int, ctypes.c_double, _P)
        ),
    }


LIBRARY = NativeLibrary(
    "olatbench_ssim", [Path(__file__).with_name("csrc") / "ssim.cpp"], per_float(_symbols)
)


def _strides(t: torch.Tensor) -> ctypes.Array:
    return (ctypes.c_int64 * 4)(*t.stride())


def _dense(t: torch.Tensor) -> torch.Tensor:
    """``t`` if contiguous or channels-last (a layout ``empty_strided`` can give its gradient), else
    a copy."""
    if t.is_contiguous() or t.is_contiguous(memory_format=torch.channels_last):
        return t
    return t.contiguous()


class _SSIMLossCPU(torch.autograd.Function):
    """(pred, gt (B, C, H, W), threads, keep) -> 0-dim ``1 - mean SSIM``; gradient for ``pred``
    only, which needs ``keep`` (save the per-pixel derivatives) to be true. Images are read in their
    own layout (no copy for NCHW or channels-last); the gradient has pred's strides."""

    @staticmethod
    def forward(
        ctx, pred: torch.Tensor, gt: torch.Tensor, threads: int, keep: bool
    ) -> torch.Tensor:
        dtype = pred.dtype
        pred, gt = _dense(pred.detach()), gt.detach()
        batch, channels, height, width = pred.shape
        derivatives = (
            torch.empty(_DERIVATIVES, batch * channels, height, width, dtype=dtype)
            if keep
            else None
        )
        ssim_sum = ctypes.c_double()
        LIBRARY.load()[
            f"olatbench_ssim_loss_forward_{float_suffix(dtype, 'the cpu SSIM kernels')}"
        ](
            pointer(pred),
            _strides(pred),
            pointer(gt),
            _strides(gt),
            batch,
            channels,
            height,
            width,
            threads,
            pointer(derivatives),
            ctypes.byref(ssim_sum),
        )
        if derivatives is not None:
            ctx.save_for_backward(pred, gt, derivatives)
        ctx.threads = threads
        return torch.tensor(1.0 - ssim_sum.value / pred.numel(), dtype=dtype)

    @staticmethod
    @once_differentiable
    def backward(ctx, grad_loss: torch.Tensor) -> tuple[torch.Tensor, None, None, None]:
        pred, gt, derivatives = ctx.saved_tensors
        batch, channels, height, width = pred.shape
        grad_pred = torch.empty_strided(pred.shape, pred.stride(), dtype=pred.dtype)
        LIBRARY.load()[
            f"olatbench_ssim_loss_backward_{float_suffix(pred.dtype, 'the cpu SSIM kernels')}"
        ](
            pointer(pred),
            _strides(pred),
            pointer(gt),
            _strides(gt),
            pointer(derivatives),
            batch,
            channels,
            height,
            width,
            ctx.threads,
            -float(grad_loss) / pred.numel(),
            pointer(grad_pred),
        )
        return grad_pred, None, None, None


def unsupported_reason(pred: torch.Tensor, gt: torch.Tensor) -> str | None:
    """Why ``ssim_loss_cpu`` cannot take these tensors, or None when it can."""
    if pred.device.type != "cpu" or gt.device.type != "cpu":
        return f"it needs CPU tensors, got {pred.device} and {gt.device}"
    if pred.dtype not in FLOAT_SUFFIXES or gt.dtype != pred.dtype:
        return f"it needs float32 or float64 tensors of one dtype, got {pred.dtype} and {gt.dtype}"
    if pred.ndim != 4 or pred.shape != gt.shape or pred.numel() == 0:
        return (
            f"it needs non-empty (B, C, H, W) tensors of one shape, got {tuple(pred.shape)} and "
            f"{tuple(gt.shape)}"
        )
    if gt.requires_grad and torch.is_grad_enabled():
        return "it has no gradient for gt, which requires grad (detach it or use the torch backend)"
    return None


def ssim_loss_cpu(pred: torch.Tensor, gt: torch.Tensor, threads: int | None = None) -> torch.Tensor:
    """``1 - SSIM`` ("3dgs" variant) of CPU (B, C, H, W) tensors of one dtype (float32 or float64):
    a 0-dim tensor, differentiable w.r.t. ``pred`` only. ``threads`` defaults to
    ``torch.get_num_threads()``.

    Raises ValueError for other inputs (see ``unsupported_reason``) and
    ``olatbench._native.BuildError`` if the kernel cannot be built."""
    reason = unsupported_reason(pred, gt)
    if reason is not None:
        raise ValueError(f"ssim_loss_cpu: {reason}")
    threads = thread_count(threads)
    return _SSIMLossCPU.apply(pred, gt, threads, torch.is_grad_enabled() and pred.requires_grad)
