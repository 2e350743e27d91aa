"""What pinning torch's CPU kernels to AVX2 costs: SSD-GS step time with ATen at the machine's best ISA vs AVX2.

torch picks its vectorised ATen kernels at import by the CPU's widest instruction set (``AVX512`` on this
machine, ``AVX2`` on many others), and the two give different rounding: a 150-step SSD-GS run on mini
``diffuse_shadow`` ended at loss 0.2841240167617798 (AVX512) vs 0.2841130495071411
(``ATEN_CPU_CAPABILITY=avx2``), so the same seed trains differently on machines of different vector width.
Setting ``ATEN_CPU_CAPABILITY=avx2`` everywhere removes that difference between x86_64 machines with AVX2
or wider. This script measures its price: ``bench_ssdgs.py`` runs in fresh processes, taking turns between
the two settings (so a shared machine's load falls on both alike), and the ratio of the median step times is
printed for each case. Example::

    python benchmarks/bench_cpu_capability.py --rounds 3
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).with_name("bench_ssdgs.py")
ROW = re.compile(r"^\s*(\w+)\s+(\d+)\s+(\d+)\s+\d+\s+([\d.]+)m")


def step_times(capability: str | None, bench_args: list[str]) -> dict[tuple[str, str, str], float]:
    """{(state, size, N): step seconds} from one bench_ssdgs run with ``ATEN_CPU_CAPABILITY=capability``."""
    env = dict(os.environ)
    env.pop("ATEN_CPU_CAPABILITY", None)
    if capability:
        env["ATEN_CPU_CAPABILITY"] = capability
    output = subprocess.run([sys.executable, str(BENCH), *bench_args], env=env, check=True, capture_output=True,
                            text=True).stdout
    return {match.group(1, 2, 3): float(match.group(4)) / 1e3
            for match in map(ROW.match, output.splitlines()) if match}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=3, help="alternating runs per setting")
    parser.add_argument("--sizes", nargs="+", default=["128"])
    parser.add_argument("--counts", nargs="+", default=["20000"])
    args = parser.parse_args()
    bench_args = ["--sizes", *args.sizes, "--counts", *args.counts, "--repeats", "3"]
    import torch

    print(f"torch {torch.__version__}, best CPU capability {torch.backends.cpu.get_cpu_capability()}")
    runs: dict[str, list[dict]] = {"native": [], "avx2": []}
    for _ in range(args.rounds):
        runs["native"].append(step_times(None, bench_args))
        runs["avx2"].append(step_times("avx2", bench_args))
    print(f"{'state':>10} {'size':>5} {'N':>6} {'native s':>9} {'avx2 s':>9} {'avx2/native':>11}")
    ratios = []
    for case in runs["native"][0]:
        native = statistics.median(run[case] for run in runs["native"])
        avx2 = statistics.median(run[case] for run in runs["avx2"])
        ratios.append(avx2 / native)
        print(f"{case[0]:>10} {case[1]:>5} {case[2]:>6} {native:>9.3f} {avx2:>9.3f} {avx2 / native:>11.2f}")
    print(f"SUMMARY bench_cpu_capability avx2_over_native_max={max(ratios):.2f} rounds={args.rounds}")


if __name__ == "__main__":
    main()
