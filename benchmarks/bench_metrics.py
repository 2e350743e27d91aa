"""Images/s of PSNR + SSIM + LPIPS (alex and vgg) at 512², olatbench vs a straightforward stack,
same run.

Straightforward stack: scikit-image ``structural_similarity`` and ``peak_signal_noise_ratio`` per
image, and LPIPS as the ``lpips`` package computes it (one image at a time, each input through the
backbone separately, default NCHW memory format) with the same weights. olatbench:
``get_protocol("olatbench-v1") .evaluate_many`` with the LPIPS backend ``torch``
(channels-last, batched) and ``onnxruntime``. Values must agree (max |Δ| printed); the target is
default path ≥ 2× the straightforward stack.

    python benchmarks/bench_metrics.py [--images 4] [--size 512] [--threads 2]

The last line is a parseable summary.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
import torch
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

from olatbench.metrics.lpips import clear_caches, get_network, resolve_backend
from olatbench.metrics.lpips_net import LPIPSNet
from olatbench.metrics.protocols import get_protocol
from olatbench.metrics.weights import find_weights


def straightforward_lpips(model: LPIPSNet, x: np.ndarray, y: np.ndarray) -> float:
    """lpips.LPIPS.forward as written: both inputs through the net separately, batch of one,
    NCHW."""

    def prepare(image):
        t = torch.from_numpy(image).permute(2, 0, 1)[None] * 2 - 1
        return (t - model.shift) / model.scale

    with torch.no_grad():
        f0, f1 = model.tapped_features(prepare(x)), model.tapped_features(prepare(y))
        total = 0.0
        for k, (a, b) in enumerate(zip(f0, f1, strict=True)):
            total += float(
                torch.nn.functional.conv2d((a - b) ** 2, getattr(model, f"lin{k}")).mean()
            )
    return total


def straightforward(pairs, models) -> tuple[float, list[dict]]:
    start = time.perf_counter()
    rows = []
    for pred, gt in pairs:
        q = [np.rint(np.clip(x, 0, 1) * 255).astype(np.float32) / 255 for x in (pred, gt)]
        rows.append(
            {
                "psnr": peak_signal_noise_ratio(q[1], q[0], data_range=1),
                "ssim": structural_similarity(
                    q[0],
                    q[1],
                    gaussian_weights=True,
                    sigma=1.5,
                    use_sample_covariance=False,
                    data_range=1,
                    channel_axis=-1,
                ),
                "lpips_alex": straightforward_lpips(models["alex"], *q),
                "lpips_vgg": straightforward_lpips(models["vgg"], *q),
            }
        )
    return time.perf_counter() - start, rows


def olatbench_path(pairs, backend: str) -> tuple[float, list[dict]]:
    protocol = dataclasses.replace(get_protocol("olatbench-v1"), lpips_backend=backend)
    protocol.evaluate_many(pairs[:1])  # warm-up: load weights, export ONNX once
    start = time.perf_counter()
    rows = protocol.evaluate_many(pairs, batch_size=4)
    return time.perf_counter() - start, rows


def max_diff(a: list[dict], b: list[dict]) -> dict[str, float]:
    return {
        k: max(abs(x[k] - y[k]) for x, y in zip(a, b, strict=True))
        for k in ("psnr", "ssim", "lpips_alex", "lpips_vgg")
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--images", type=int, default=4)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    if any(find_weights(net) is None for net in ("alex", "vgg")):
        raise SystemExit("LPIPS weights are not installed: run `olatbench weights install` first")
    rng = np.random.default_rng(0)
    pairs = []
    for _ in range(args.images):
        gt = rng.random((args.size, args.size, 3), dtype=np.float32)
        pairs.append(
            (np.clip(gt + 0.05 * rng.standard_normal(gt.shape).astype(np.float32), 0, 1), gt)
        )
    clear_caches()
    models = {
        net: get_network(net).to(memory_format=torch.contiguous_format) for net in ("alex", "vgg")
    }
    models = {net: LPIPSNet(net).load_lpips_state(m.state_dict()) for net, m in models.items()}
    clear_caches()
    straightforward(pairs[:1], models)  # warm-up
    t_ref, ref_rows = straightforward(pairs, models)
    results = {}
    for backend in ("torch", "onnxruntime"):
        elapsed, rows = olatbench_path(pairs, backend)
        results[backend] = (elapsed, max_diff(rows, ref_rows))
    default = resolve_backend("auto")
    n = args.images
    print(
        f"{n} images {args.size}², {args.threads} threads, PSNR + SSIM + LPIPS alex + vgg "
        "(olatbench-v1)"
    )
    print(f"  straightforward (scikit-image + per-image lpips-style torch): {n / t_ref:7.3f} img/s")
    for backend, (elapsed, diff) in results.items():
        shown = ", ".join(f"{k} {v:.1e}" for k, v in diff.items())
        print(
            f"  olatbench LPIPS backend {backend:12s}: {n / elapsed:7.3f} img/s  "
            f"({t_ref / elapsed:.2f}×)  max |Δ|: {shown}"
        )
    elapsed, diff = results[default]
    agree = (
        diff["ssim"] < 1e-5
        and diff["psnr"] < 1e-4
        and diff["lpips_alex"] < 1e-5
        and diff["lpips_vgg"] < 1e-5
    )
    speedup = t_ref / elapsed
    print(
        f"SUMMARY bench_metrics default_backend={default} default_img_s={n / elapsed:.3f} "
        f"reference_img_s={n / t_ref:.3f} speedup={speedup:.2f} target=2.0 "
        f"values_agree={'yes' if agree else 'NO'} "
        f"status={'ok' if speedup >= 2 and agree else 'below-target'}"
    )


if __name__ == "__main__":
    main()
