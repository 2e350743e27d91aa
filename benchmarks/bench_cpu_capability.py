"""What pinning the CPU numerics costs: SSD-GS step time under each setting of the rounding
variables, as ratios.

torch picks its vectorised ATen kernels at import by the CPU's widest instruction set (``AVX512`` on
many machines, ``AVX2`` on others), and MKL and oneDNN choose their own kernels by the CPU; each
choice rounds differently, so the same seed trains to other last digits (docs/runner.md, "Same seed,
same numbers"). The ``olatbench`` command pins ATen to AVX2 (`olatbench.numerics.PINS`); MKL's
conditional numerical reproducibility (``MKL_CBWR=AVX2``) would pin its code path too. This script
measures the price of each setting: ``bench_ssdgs.py`` runs in fresh processes, one per setting per
round, the settings taking turns (so a shared machine's load falls on all alike), each with every
variable of `olatbench.numerics.ROUNDING_ENV` but the thread counts removed and then the setting's
set. The median step time of each setting is printed with its ratio to the first setting's, and the
load average before and after (a ratio under heavy load says little). Example::

    python benchmarks/bench_cpu_capability.py --rounds 3
    python benchmarks/bench_cpu_capability.py --setting native= \\
        --setting cbwr=ATEN_CPU_CAPABILITY=avx2,MKL_CBWR=AVX2
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path

from olatbench.numerics import ROUNDING_ENV

BENCH = Path(__file__).with_name("bench_ssdgs.py")
ROW = re.compile(r"^\s*(\w+)\s+(\d+)\s+(\d+)\s+\d+\s+([\d.]+)m")
THREAD_ENV = ("OMP_NUM_THREADS", "MKL_NUM_THREADS")
#: name -> environment: torch's own choice, the olatbench pin, the pin with MKL's AVX2 code path
DEFAULT_SETTINGS = {
    "native": {},
    "pinned": {"ATEN_CPU_CAPABILITY": "avx2"},
    "pinned+MKL_CBWR": {"ATEN_CPU_CAPABILITY": "avx2", "MKL_CBWR": "AVX2"},
}


def parse_setting(text: str) -> tuple[str, dict[str, str]]:
    """``NAME=VAR=VALUE,VAR=VALUE`` (or ``NAME=`` for nothing set) as (name, environment)."""
    name, _, assignments = text.partition("=")
    pairs = [item for item in assignments.split(",") if item]
    if not name or any("=" not in pair for pair in pairs):
        raise argparse.ArgumentTypeError(
            f"--setting {text!r}: expected NAME=VAR=VALUE,VAR=VALUE or NAME="
        )
    return name, dict(pair.split("=", 1) for pair in pairs)


def step_times(setting: dict[str, str], bench_args: list[str]) -> dict[tuple[str, str, str], float]:
    """{(state, size, N): step seconds} from one bench_ssdgs run under ``setting``."""
    env = {
        key: value
        for key, value in os.environ.items()
        if key not in ROUNDING_ENV or key in THREAD_ENV
    }
    env.update(setting)
    output = subprocess.run(
        [sys.executable, str(BENCH), *bench_args],
        env=env,
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return {
        match.group(1, 2, 3): float(match.group(4)) / 1e3
        for match in map(ROW.match, output.splitlines())
        if match
    }


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--rounds", type=int, default=3, help="alternating runs per setting")
    parser.add_argument("--sizes", nargs="+", default=["128"])
    parser.add_argument("--counts", nargs="+", default=["20000"])
    parser.add_argument(
        "--setting",
        action="append",
        type=parse_setting,
        metavar="NAME=VAR=VALUE,...",
        help="a setting to time (repeatable; the first is the reference; default: "
        + ", ".join(f"{k} {v or '{}'}" for k, v in DEFAULT_SETTINGS.items())
        + ")",
    )
    args = parser.parse_args()
    settings = dict(args.setting) if args.setting else DEFAULT_SETTINGS
    bench_args = ["--sizes", *args.sizes, "--counts", *args.counts, "--repeats", "3", "--no-bf16"]
    import torch

    print(
        f"torch {torch.__version__}, best CPU capability "
        f"{torch.backends.cpu.get_cpu_capability()}, load average before {os.getloadavg()[0]:.1f}"
    )
    runs: dict[str, list[dict]] = {name: [] for name in settings}
    for _ in range(args.rounds):
        for name, setting in settings.items():
            runs[name].append(step_times(setting, bench_args))
    reference = next(iter(settings))
    print(
        f"{'state':>10} {'size':>5} {'N':>6} "
        + " ".join(f"{name + ' s':>16}" for name in settings)
        + " "
        + " ".join(f"{name + '/' + reference:>24}" for name in list(settings)[1:])
    )
    worst = dict.fromkeys(list(settings)[1:], 0.0)
    for case in runs[reference][0]:
        medians = {name: statistics.median(run[case] for run in runs[name]) for name in settings}
        ratios = {name: medians[name] / medians[reference] for name in worst}
        worst = {name: max(worst[name], ratios[name]) for name in worst}
        print(
            f"{case[0]:>10} {case[1]:>5} {case[2]:>6} "
            + " ".join(f"{medians[n]:>16.3f}" for n in settings)
            + " "
            + " ".join(f"{ratios[n]:>24.2f}" for n in worst)
        )
    print(
        "SUMMARY bench_cpu_capability "
        + " ".join(f"{name}_over_{reference}_max={ratio:.2f}" for name, ratio in worst.items())
        + f" rounds={args.rounds} load_average_after={os.getloadavg()[0]:.1f}"
    )


if __name__ == "__main__":
    main()
