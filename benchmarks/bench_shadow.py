"""Light-view shadow pass benchmark: ``shadow_gather`` with the C++ kernel vs the torch reference,
same run.

Scene: 20 000 Gaussians uniformly in the unit ball with 3DGS-like scales (log-uniform 0.005–0.04)
and random opacities; a point light at distance 4 looking at the centre; light camera 256² fitted to
the ball. Both backends run the same full call (light camera, projection, binning by squared
distance, compositing, per-Gaussian reductions) with the default options
(``mode="uniform"``, ``depth_offset=0``) and must agree; then both run ``mode="uniform"`` with the
self-shadow offset ``--offset`` (default the official 0.015; the C++ kernel's lagging second
transmittance) and the C++ time is compared with torch and with C++ at offset 0. Last, the
official-kernel options the suite presets use (``OFFICIAL_KERNEL``: density mode, offset 0.015) run
on both backends, which must agree, and the C++/torch ratio is printed. Targets: C++ light pass ≤ 60
ms at 256² with 20 000 Gaussians (offset 0); the official options ≥ 10× faster in C++ than in torch.

Timings on a machine shared with other jobs are noisy; the median of ``--repeats`` calls is
reported. Set ``OMP_WAIT_POLICY=PASSIVE`` on oversubscribed machines (spinning OpenMP workers
inflate torch's small ops). Ends with one ``RESULT key=value ...`` line.

Usage: ``python benchmarks/bench_shadow.py [--gaussians 20000] [--size 256] [--threads 2]
[--repeats 5] [--offset 0.015]``
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import torch

from olatbench.gaussians.backends import cpu_backend_status
from olatbench.gaussians.shadow import OFFICIAL_DEPTH_OFFSET, OFFICIAL_KERNEL, shadow_gather

TARGET_MS = 60.0
TARGET_OFFICIAL_SPEEDUP = 10.0


def make_scene(n: int, seed: int = 0) -> tuple[torch.Tensor, ...]:
    g = torch.Generator().manual_seed(seed)
    direction = torch.randn(n, 3, generator=g)
    direction /= direction.norm(dim=-1, keepdim=True)
    means = direction * torch.rand(n, 1, generator=g) ** (1 / 3)
    quats = torch.randn(n, 4, generator=g)
    scales = torch.exp(torch.empty(n, 3).uniform_(math.log(0.005), math.log(0.04), generator=g))
    opacities = torch.empty(n).uniform_(0.05, 0.95, generator=g)
    light = torch.tensor([2.0, -3.0, 1.8])
    light = light / light.norm() * 4.0
    return means, quats, scales, opacities, light, torch.zeros(3)


def median_ms(fn, repeats: int, clock=time.perf_counter) -> float:
    """Median duration of ``fn`` in ms by ``clock`` (wall by default; ``time.process_time`` = CPU of
    all threads)."""
    times = []
    for _ in range(repeats):
        start = clock()
        fn()
        times.append((clock() - start) * 1e3)
    return statistics.median(times)


def _kernel_only_ms(
    scene: tuple[torch.Tensor, ...], size: int, repeats: int, depth_offset: float = 0.0
) -> float:
    """Time of ``shadow_gather_cpu`` alone on the same projected, binned scene."""
    from olatbench.gaussians.backends.cpu import shadow_gather_cpu
    from olatbench.gaussians.projection import project
    from olatbench.gaussians.shadow import light_camera
    from olatbench.gaussians.tiles import bin_gaussians

    means, quats, scales, opacities, light, target = scene
    w2c, K, width, height = light_camera(
        light, target, float((means - target).norm(dim=1).max()), size
    )
    projected = project(means, quats, scales, w2c, K, width, height)
    keys = ((means - light) ** 2).sum(-1)
    bins = bin_gaussians(projected.means2d, projected.radii, keys, width, height)
    return median_ms(
        lambda: shadow_gather_cpu(
            projected.means2d,
            projected.conics,
            opacities,
            bins,
            sort_keys=keys,
            depth_offset=depth_offset,
        ),
        repeats,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gaussians", type=int, default=20_000)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument(
        "--offset",
        type=float,
        default=OFFICIAL_DEPTH_OFFSET,
        help="depth_offset (squared-distance units) of the offset rows (> 0)",
    )
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    scene = make_scene(args.gaussians)
    ok, detail = cpu_backend_status()
    if not ok:
        print(f"C++ backend unavailable: {detail}")

    def run(backend: str, **options):
        return shadow_gather(*scene, resolution=args.size, backend=backend, **options)

    reference = run("torch")
    torch_ms = median_ms(lambda: run("torch"), max(1, args.repeats // 2))
    offset_reference = run("torch", depth_offset=args.offset)
    torch_offset_ms = median_ms(
        lambda: run("torch", depth_offset=args.offset), max(1, args.repeats // 2)
    )
    official_reference = run("torch", **OFFICIAL_KERNEL)
    official_ms = median_ms(lambda: run("torch", **OFFICIAL_KERNEL), max(1, args.repeats // 2))
    print(
        f"scene: {args.gaussians} Gaussians, light camera {args.size}², {args.threads} threads; "
        f"seen {int(reference.seen.sum())}, mean visibility "
        f"{float(reference.visibility[reference.seen].mean()):.3f}"
    )
    print(f"torch reference (uniform, offset 0):   {torch_ms:9.1f} ms")
    print(f"torch reference (uniform, offset {args.offset:g}): {torch_offset_ms:9.1f} ms")
    print(f"torch official kernel options:         {official_ms:9.1f} ms")
    cpu_ms = kernel_ms = cpu_time_ms = agree = float("nan")
    cpu_offset_ms = kernel_offset_ms = cpu_offset_time_ms = offset_agree = float("nan")
    official_cpu_ms = official_agree = float("nan")
    if ok:
        run("cpu")  # warm-up (library load)
        cpu_ms = median_ms(lambda: run("cpu"), args.repeats)
        cpu_time_ms = median_ms(lambda: run("cpu"), args.repeats, clock=time.process_time)
        result = run("cpu")
        agree = float((result.visibility - reference.visibility).abs().max())
        print(
            f"C++ kernel (uniform, offset 0):        {cpu_ms:9.1f} ms   (x{torch_ms / cpu_ms:.1f} "
            f"vs torch; {cpu_time_ms:.1f} ms CPU time over all threads)"
        )
        kernel_ms = _kernel_only_ms(scene, args.size, args.repeats)
        print(
            f"  of which the C++ compositing kernel alone: {kernel_ms:9.1f} ms (rest: projection "
            "+ binning)"
        )
        same_seen = torch.equal(result.seen, reference.seen)
        print(f"max |visibility C++ - torch| = {agree:.2e}; seen flags equal: {same_seen}")
        cpu_offset_ms = median_ms(lambda: run("cpu", depth_offset=args.offset), args.repeats)
        cpu_offset_time_ms = median_ms(
            lambda: run("cpu", depth_offset=args.offset), args.repeats, time.process_time
        )
        kernel_offset_ms = _kernel_only_ms(scene, args.size, args.repeats, args.offset)
        offset_result = run("cpu", depth_offset=args.offset)
        offset_agree = float((offset_result.visibility - offset_reference.visibility).abs().max())
        changed = float((offset_result.visibility - result.visibility).abs().mean())
        print(
            f"C++ kernel (uniform, offset {args.offset:g}):    {cpu_offset_ms:9.1f} ms   "
            f"(x{torch_offset_ms / cpu_offset_ms:.1f} vs torch with the offset; "
            f"x{cpu_offset_ms / cpu_ms:.2f} the time of C++ at offset 0; {cpu_offset_time_ms:.1f} "
            f"ms CPU time, x{cpu_offset_time_ms / cpu_time_ms:.2f})"
        )
        print(
            f"  of which the C++ compositing kernel alone: {kernel_offset_ms:9.1f} ms "
            f"(x{kernel_offset_ms / kernel_ms:.2f} the kernel at offset 0)"
        )
        print(
            f"max |visibility C++ - torch| with the offset = {offset_agree:.2e}; "
            f"mean |change| from offset 0 = {changed:.3f}"
        )
        official_cpu_ms = median_ms(lambda: run("cpu", **OFFICIAL_KERNEL), args.repeats)
        official_result = run("cpu", **OFFICIAL_KERNEL)
        official_agree = float(
            (official_result.visibility - official_reference.visibility).abs().max()
        )
        print(
            f"C++ kernel, official options (density, offset {OFFICIAL_KERNEL['depth_offset']:g}): "
            f"{official_cpu_ms:9.1f} ms   C++/torch speed-up {official_ms / official_cpu_ms:.1f}x "
            f"(target ≥ {TARGET_OFFICIAL_SPEEDUP:.0f}x); max |visibility C++ - torch| = "
            f"{official_agree:.2e}; seen flags equal: "
            f"{torch.equal(official_result.seen, official_reference.seen)}"
        )
    passed = ok and cpu_ms <= TARGET_MS and official_ms / official_cpu_ms >= TARGET_OFFICIAL_SPEEDUP
    print(
        f"RESULT bench=shadow gaussians={args.gaussians} size={args.size} threads={args.threads} "
        f"cpu_ms={cpu_ms:.1f} cpu_kernel_ms={kernel_ms:.1f} torch_ms={torch_ms:.1f} "
        f"official_torch_ms={official_ms:.1f} official_cpu_ms={official_cpu_ms:.1f} "
        f"official_speedup={official_ms / official_cpu_ms:.1f} "
        f"official_max_abs_diff={official_agree:.2e} cpu_process_ms={cpu_time_ms:.1f} "
        f"speedup={torch_ms / cpu_ms:.1f} max_abs_diff={agree:.2e} offset={args.offset:g} "
        f"cpu_offset_ms={cpu_offset_ms:.1f} cpu_kernel_offset_ms={kernel_offset_ms:.1f} "
        f"cpu_offset_process_ms={cpu_offset_time_ms:.1f} torch_offset_ms={torch_offset_ms:.1f} "
        f"offset_speedup={torch_offset_ms / cpu_offset_ms:.1f} "
        f"offset_cost={cpu_offset_ms / cpu_ms:.2f} offset_max_abs_diff={offset_agree:.2e} "
        f"target_ms={TARGET_MS:.0f} pass={passed}"
    )


if __name__ == "__main__":
    main()
