"""Cost of the stages that run as torch code on a GPU: the light pass and SSD-GS shading, torch vs
C++, at paper scale.

On CUDA tensors the light-view pass (``shadow_gather``) and the SSD-GS shading (``Shader.forward``)
run their torch implementations; on the CPU their C++ kernels. This measures both on the CPU, in the
same run, at a ``--size``² light view (default 512, the paper's resolution) with ``--counts``
Gaussians (default 100K and 550K, the sizes of the paper's scenes): the wall time (median of
``--repeats`` after one warm-up) and the peak memory the call adds. Each (stage, backend, count)
runs in a fresh subprocess, so its peak resident set is its own: "peak MB" is ``ru_maxrss`` after
the calls minus ``ru_maxrss`` once the inputs exist (an upper bound on the working memory the call
needs, which on a GPU is device memory).

- light pass: ``shadow_gather`` (projection, binning by squared light distance, compositing,
  per-Gaussian sums, ``mode="uniform"``) on N Gaussians in the unit ball (log-uniform scales
  0.005–0.04, opacities 0.05–0.95), the light at distance 4; forward only (as in training);
- shading: ``Shader.forward`` of the default SSD-GS config with every term on (specular, SSS,
  shadow, the real Θ_SSS and Θ_shad networks) on N Gaussians, plus ``colour.sum().backward()``
  (as in training).

``--quick`` runs 100K only with two repeats. Ends with one ``SUMMARY bench_gpu_path key=value ...``
line.

Usage: ``python benchmarks/bench_gpu_path.py [--counts 100000 550000] [--size 512] [--repeats 3]
[--quick]``
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import statistics
import subprocess
import sys
import time

import torch

STAGES = ("light_pass", "shading")
BACKENDS = ("cpu", "torch")


def light_pass_call(count: int, size: int, backend: str):
    # the same random ball of Gaussians and light as bench_shadow.py
    from bench_shadow import make_scene

    from olatbench.gaussians.shadow import shadow_gather

    scene = make_scene(count)

    def run() -> None:
        shadow_gather(*scene, resolution=size, backend=backend)

    return run


def shading_call(count: int, size: int, backend: str):
    del size
    from olatbench.methods.ssdgs.config import SSDGSConfig
    from olatbench.methods.ssdgs.shader import Shader

    config = SSDGSConfig()
    shader = Shader(config, backend=backend)
    g = torch.Generator().manual_seed(0)
    positions = torch.nn.functional.normalize(torch.randn(count, 3, generator=g), dim=-1) * 0.9
    quats = torch.randn(count, 4, generator=g)
    scales = torch.exp(torch.empty(count, 3).uniform_(math.log(0.005), math.log(0.05), generator=g))
    dims = {
        "diffuse": 3,
        "specular": 3,
        "sss": 3,
        "asg_weights": config.num_asg,
        "material": config.material_dim,
    }
    attributes = {name: torch.randn(count, d, generator=g) for name, d in dims.items()}
    coarse = torch.rand(count, generator=g)
    camera, light, intensity = (
        torch.tensor([0.0, -3.0, 1.0]),
        torch.tensor([2.0, -3.0, 3.0]),
        torch.full((3,), 16.0),
    )

    def run() -> None:
        leaves = {name: value.clone().requires_grad_(True) for name, value in attributes.items()}
        p, q = positions.clone().requires_grad_(True), quats.clone().requires_grad_(True)
        out = shader(
            p,
            q,
            scales,
            leaves,
            camera,
            light,
            intensity,
            frozenset({"specular", "sss", "shadow"}),
            coarse,
        )
        out.colour.sum().backward()

    return run


def worker(stage: str, backend: str, count: int, size: int, repeats: int) -> None:
    """Measure one (stage, backend, count) in this process and print one JSON line."""
    run = {"light_pass": light_pass_call, "shading": shading_call}[stage](count, size, backend)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    times = []
    for _ in range(repeats + 1):  # the first is the warm-up (C++ build load, allocator growth)
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(json.dumps({"seconds": statistics.median(times[1:]), "peak_mb": (peak - before) / 1024}))


def measure(stage: str, backend: str, count: int, size: int, repeats: int) -> dict[str, float]:
    args = [
        sys.executable,
        __file__,
        "--worker",
        stage,
        backend,
        str(count),
        "--size",
        str(size),
        "--repeats",
        str(repeats),
    ]
    done = subprocess.run(args, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--counts", type=int, nargs="+", default=[100_000, 550_000])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="100K Gaussians, 2 repeats")
    parser.add_argument(
        "--worker", nargs=3, metavar=("STAGE", "BACKEND", "COUNT"), help=argparse.SUPPRESS
    )
    args = parser.parse_args()
    if args.worker:
        stage, backend, count = args.worker
        worker(stage, backend, int(count), args.size, args.repeats)
        return
    counts, repeats = ([100_000], 2) if args.quick else (args.counts, args.repeats)
    print(
        f"torch {torch.__version__}, {torch.get_num_threads()} threads, light view {args.size}², "
        f"median of {repeats} after a warm-up, each in its own process"
    )
    print(
        f"{'stage':<11} {'N':>8} {'C++ s':>8} {'torch s':>8} {'ratio':>6} {'C++ MB':>8} "
        f"{'torch MB':>9}"
    )
    summary = []
    for stage in STAGES:
        for count in counts:
            cpp, ref = (measure(stage, b, count, args.size, repeats) for b in BACKENDS)
            ratio = ref["seconds"] / cpp["seconds"]
            print(
                f"{stage:<11} {count:>8} {cpp['seconds']:>8.2f} {ref['seconds']:>8.2f} "
                f"{ratio:>6.1f} {cpp['peak_mb']:>8.0f} {ref['peak_mb']:>9.0f}",
                flush=True,
            )
            summary.append(
                f"{stage}_{count}_ratio={ratio:.2f} {stage}_{count}_torch_mb={ref['peak_mb']:.0f}"
            )
    print("SUMMARY bench_gpu_path " + " ".join(summary))


if __name__ == "__main__":
    main()
