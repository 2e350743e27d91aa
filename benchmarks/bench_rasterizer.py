"""Rasterizer benchmark: C++ CPU backend vs the torch reference, measured in the same run.

Scene: 20 000 Gaussians with 12 feature channels in a ball in front of the camera, rendered at 256²
and 512² with 2 threads. For each backend and size it reports the median time of ``render()``
forward (no grad) and forward + backward (projection, binning, compositing and the backward of all
of it), and the peak RSS of a separate worker process that ran only that backend. Also times the
light-view pass (projection from the light, binning by squared distance, ``shadow_gather_cpu``) at
256². Targets: CPU fwd+bwd ≥ 10× faster than torch at 256², light pass ≤ 60 ms. Ends with one
``RESULT key=value ...`` line.

Workers run with ``OMP_WAIT_POLICY=PASSIVE`` by default (``--omp-wait-policy ""`` inherits the
environment): on oversubscribed machines the default spinning OpenMP workers of torch's many small
ops (projection, binning) burn the shared cores and inflate every timing several-fold; the setting
applies to both backends.

Usage: ``python benchmarks/bench_rasterizer.py [--gaussians 20000] [--sizes 256 512] [--threads 2]``
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import time

import torch


def make_scene(n: int, channels: int, size: int, seed: int = 0) -> dict:
    """Gaussians uniformly in a ball of radius 1 at distance 3, seen by a 40°-FoV camera at the
    origin."""
    g = torch.Generator().manual_seed(seed)
    direction = torch.randn(n, 3, generator=g)
    direction /= direction.norm(dim=-1, keepdim=True)
    means = direction * torch.rand(n, 1, generator=g) ** (1 / 3)
    means[:, 2] += 3.0
    focal = 0.5 * size / math.tan(math.radians(20.0))
    return {
        "means": means,
        "quats": torch.randn(n, 4, generator=g),
        "scales": torch.exp(
            torch.empty(n, 3).uniform_(math.log(0.005), math.log(0.04), generator=g)
        ),
        "opacities": torch.empty(n).uniform_(0.05, 0.95, generator=g),
        "features": torch.rand(n, channels, generator=g),
        "background": torch.zeros(channels),
        "w2c": torch.eye(4),
        "K": torch.tensor([[focal, 0.0, size / 2], [0.0, focal, size / 2], [0.0, 0.0, 1.0]]),
    }


def median_ms(fn, repeats: int) -> tuple[float, float]:
    """Median wall-clock ms and median process CPU ms (summed over threads) of ``fn``."""
    wall, cpu = [], []
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        fn()
        wall.append((time.perf_counter() - start) * 1e3)
        cpu.append((time.process_time() - start_cpu) * 1e3)
    return statistics.median(wall), statistics.median(cpu)


def worker(backend: str, size: int, n: int, threads: int, repeats: int) -> dict:
    from olatbench.gaussians.render import render

    torch.set_num_threads(threads)
    s = make_scene(n, 12, size)
    params = {
        k: s[k].clone().requires_grad_()
        for k in ("means", "quats", "scales", "opacities", "features")
    }

    def run(grad: bool):
        with torch.set_grad_enabled(grad):
            out = render(
                params["means"],
                params["quats"],
                params["scales"],
                params["opacities"],
                params["features"],
                s["w2c"],
                s["K"],
                size,
                size,
                s["background"],
                backend=backend,
                threads=threads,
            )
            if grad:
                (out["image"].square().mean() + out["alpha"].mean()).backward()
        return out

    out = run(False)  # warm-up (also builds the C++ library on first use)
    if backend != "torch":  # the torch reference is too slow to warm up its backward too
        run(True)
    result = {"coverage": float(out["alpha"].mean()), "visible": int(out["visible"].sum())}
    result["fwd_ms"], result["fwd_cpu_ms"] = median_ms(lambda: run(False), repeats)
    result["fwdbwd_ms"], result["fwdbwd_cpu_ms"] = median_ms(lambda: run(True), repeats)
    if backend == "cpu" and size == 256:
        result["light_ms"], result["light_cpu_ms"] = median_ms(
            lambda: light_pass(s, size, threads), max(repeats, 5)
        )
    result["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return result


def light_pass(s: dict, size: int, threads: int) -> None:
    """Light camera at (2, -2, 0) looking at the ball; projection + binning by squared distance +
    gather."""
    from olatbench.gaussians.backends.cpu import shadow_gather_cpu
    from olatbench.gaussians.projection import project
    from olatbench.gaussians.tiles import bin_gaussians

    light = torch.tensor([2.0, -2.0, 0.0])
    forward = torch.tensor([0.0, 0.0, 3.0]) - light
    forward /= forward.norm()
    right = torch.linalg.cross(forward, torch.tensor([0.0, 0.0, 1.0]))
    right /= right.norm()
    down = torch.linalg.cross(forward, right)
    rot = torch.stack([right, down, forward])
    w2c = torch.eye(4)
    w2c[:3, :3], w2c[:3, 3] = rot, -rot @ light
    with torch.no_grad():
        p = project(s["means"], s["quats"], s["scales"], w2c, s["K"], size, size)
        bins = bin_gaussians(p.means2d, p.radii, (s["means"] - light).square().sum(-1), size, size)
        shadow_gather_cpu(p.means2d, p.conics, s["opacities"], bins, radius_px=2.0, threads=threads)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--gaussians", type=int, default=20000)
    parser.add_argument("--sizes", type=int, nargs="+", default=[256, 512])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats for the cpu backend")
    parser.add_argument(
        "--torch-repeats", type=int, default=1, help="timed repeats for the (slow) torch backend"
    )
    parser.add_argument(
        "--omp-wait-policy", default="PASSIVE", help="OMP_WAIT_POLICY for the workers"
    )
    parser.add_argument("--worker", nargs=2, metavar=("BACKEND", "SIZE"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        backend, size = args.worker[0], int(args.worker[1])
        print(json.dumps(worker(backend, size, args.gaussians, args.threads, args.repeats)))
        return

    summary = {}
    env = dict(os.environ)
    if args.omp_wait_policy:
        env["OMP_WAIT_POLICY"] = args.omp_wait_policy
    print(
        f"{args.gaussians} Gaussians, 12 channels, {args.threads} threads, median of "
        f"{args.repeats} (cpu) / {args.torch_repeats} (torch) after a warm-up, "
        f"OMP_WAIT_POLICY={env.get('OMP_WAIT_POLICY', '')}"
    )
    print("wall-clock ms, with the process CPU time (all threads) in brackets")
    print(
        f"{'size':>5} {'backend':>8} {'fwd ms':>17} {'fwd+bwd ms':>17} {'peak RSS MB':>12} "
        f"{'coverage':>9}"
    )
    for size in args.sizes:
        for backend in ("cpu", "torch"):
            repeats = args.repeats if backend == "cpu" else args.torch_repeats
            command = [
                sys.executable,
                __file__,
                "--worker",
                backend,
                str(size),
                "--gaussians",
                str(args.gaussians),
                "--threads",
                str(args.threads),
                "--repeats",
                str(repeats),
            ]
            run = subprocess.run(command, capture_output=True, text=True, env=env)
            if run.returncode != 0:
                sys.exit(f"worker {backend} {size} failed:\n{run.stderr}")
            r = json.loads(run.stdout)
            fwd = f"{r['fwd_ms']:.1f} [{r['fwd_cpu_ms']:.0f}]"
            fwdbwd = f"{r['fwdbwd_ms']:.1f} [{r['fwdbwd_cpu_ms']:.0f}]"
            print(
                f"{size:>5} {backend:>8} {fwd:>17} {fwdbwd:>17} {r['peak_rss_mb']:>12.0f} "
                f"{r['coverage']:>9.3f}"
            )
            summary[f"{backend}_fwd_{size}_ms"] = r["fwd_ms"]
            summary[f"{backend}_fwdbwd_{size}_ms"] = r["fwdbwd_ms"]
            summary[f"{backend}_rss_{size}_mb"] = r["peak_rss_mb"]
            if "light_ms" in r:
                summary[f"light_{size}_ms"] = r["light_ms"]
                summary[f"light_{size}_cpu_ms"] = r["light_cpu_ms"]
        summary[f"speedup_fwd_{size}"] = (
            summary[f"torch_fwd_{size}_ms"] / summary[f"cpu_fwd_{size}_ms"]
        )
        summary[f"speedup_fwdbwd_{size}"] = (
            summary[f"torch_fwdbwd_{size}_ms"] / summary[f"cpu_fwdbwd_{size}_ms"]
        )
        print(f"{size:>5} cpu/torch speed-up: fwd {summary[f'speedup_fwd_{size}']:.1f}x, "
              f"fwd+bwd {summary[f'speedup_fwdbwd_{size}']:.1f}x")  # fmt: skip
    if "light_256_ms" in summary:
        light, light_cpu = summary["light_256_ms"], summary["light_256_cpu_ms"]
        print(f"light pass at 256²: {light:.1f} ms [{light_cpu:.0f}] (target ≤ 60 ms)")
        summary["light_target_met"] = summary["light_256_ms"] <= 60.0
    if "speedup_fwdbwd_256" in summary:
        summary["speedup_target_met"] = summary["speedup_fwdbwd_256"] >= 10.0
    fields = " ".join(
        f"{k}={v:.2f}" if isinstance(v, float) else f"{k}={v}" for k, v in summary.items()
    )
    print(f"RESULT gaussians={args.gaussians} threads={args.threads} {fields}")


if __name__ == "__main__":
    main()
