"""SSIM training-loss benchmark: the C++ kernel (``backend="cpu"``) vs the torch reference, in one
process.

Times ``ssim_loss(pred, gt, variant="3dgs", channels_last=True)`` on float32 (H, W, 3) images, the
call of ``olatbench.methods.training.photometric_loss``: "fwd" is the loss with its autograd graph
recorded (pred requires grad), "fwd+bwd" adds ``loss.backward()``. Each timing is the fastest of
``--repeats`` runs after a warm-up (which also builds the C++ library on first use), the backends
alternating run by run. Also checks that both backends give the same loss and gradient. Target:
fwd+bwd ≥ 5× faster than torch at every size. Ends with one ``SUMMARY bench_ssim key=value ...``
line.

Usage: ``python benchmarks/bench_ssim.py [--sizes 128 256] [--threads 2] [--repeats 30]``
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import torch
from backend_speedup import BACKENDS, SpeedupTable

from olatbench.metrics.ssim import ssim_loss

TARGET = 5.0


def images(size: int, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """A random (size, size, 3) float32 prediction and a noisy, clamped target."""
    g = torch.Generator().manual_seed(seed)
    pred = torch.rand(size, size, 3, generator=g)
    return pred, (pred + 0.1 * torch.randn(size, size, 3, generator=g)).clamp(0, 1)


def step(pred: torch.Tensor, gt: torch.Tensor, backend: str, backward: bool) -> Callable[[], None]:
    """One loss evaluation (and backward) on a fresh leaf."""

    def run() -> None:
        leaf = pred.detach().requires_grad_(True)
        loss = ssim_loss(leaf, gt, channels_last=True, backend=backend)
        if backward:
            loss.backward()

    return run


def max_differences(pred: torch.Tensor, gt: torch.Tensor) -> tuple[float, float]:
    """|Δ loss| and max |Δ gradient| / max |gradient| between the backends."""
    out = {}
    for backend in BACKENDS:
        leaf = pred.detach().requires_grad_(True)
        loss = ssim_loss(leaf, gt, channels_last=True, backend=backend)
        loss.backward()
        out[backend] = (float(loss.detach()), leaf.grad)
    (loss_t, grad_t), (loss_c, grad_c) = out["torch"], out["cpu"]
    return abs(loss_t - loss_c), float((grad_t - grad_c).abs().max() / grad_t.abs().max())


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sizes", type=int, nargs="+", default=[128, 256])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=30)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)

    print(
        f"ssim_loss float32 (H, W, 3), channels_last, {args.threads} threads, fastest of "
        f"{args.repeats} (ms)"
    )
    table = SpeedupTable("size")
    for size in args.sizes:
        pred, gt = images(size)
        speedups = table.measure(
            size,
            lambda backend, backward, p=pred, g=gt: step(p, g, backend, backward),
            args.repeats,
        )
        d_loss, d_grad = max_differences(pred, gt)
        table.agree = table.agree and d_loss < 1e-5 and d_grad < 1e-4
        print(f"{size:>6} {speedups}; |Δ loss| {d_loss:.1e}, relative max |Δ grad| {d_grad:.1e}")
    print(table.summary("bench_ssim", args.threads, TARGET))


if __name__ == "__main__":
    main()
