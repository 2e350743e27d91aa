"""Seconds per training step of the authors' code on the CPU (``--code device=cpu``) against the
native method, measured in turns in one run: ``ssdgs`` / ``ssdgs-official`` and ``gs3`` /
``gs3-official``.

Each round trains the native method and then its official counterpart on the same mini scene, seed
and length through ``olatbench run`` (mini presets at ``--iterations``: the same schedule, initial
points and Gaussian budget; docs/official.md), one job at a time, every process limited to
``--threads`` threads. A step's time is the training loop's wall time over its steps: the native
job's ``timing.train_seconds``; for the official job the elapsed time its own ``Training progress``
bar (tqdm) printed at its last step, which leaves out interpreter start, imports and scene loading.
Per method pair and round the script prints both times and ``official / native``; the last line per
pair is a parseable summary with the median ratio over rounds. Needs the pinned checkouts and the
official environment (docs/official.md, "The official environment")::

    python benchmarks/bench_official_cpu.py --ssdgs-code /work/ext/ssdgs --gs3-code /work/ext/gs3 \\
        --python /work/ext/official-venv/bin/python --iterations 1000 --rounds 2
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

_PROGRESS = re.compile(r"Training progress: 100%\|[^|]*\| (\d+)/(\d+) \[(?:(\d+):)?(\d+):(\d+)<")


def loop_seconds(log: str) -> float:
    """Elapsed seconds of the last complete ``Training progress`` bar in an official job's log."""
    matches = [m for m in _PROGRESS.finditer(log.replace("\r", "\n")) if m[1] == m[2]]
    if not matches:
        raise RuntimeError("no complete 'Training progress' bar in the official job's log")
    hours, minutes, seconds = (int(value or 0) for value in matches[-1].groups()[2:])
    return 3600.0 * hours + 60.0 * minutes + seconds


def train(
    method: str, scene: str, iterations: int, out: Path, code: list[str], threads: int
) -> float:
    """Run one job and return its seconds per training step (module docstring)."""
    argv = [
        sys.executable,
        "-m",
        "olatbench",
        "run",
        "--method",
        method,
        "--suite",
        "mini",
        "--scenes",
        scene,
        "--iterations",
        str(iterations),
        "--jobs",
        "1",
        "-o",
        str(out),
        "--quiet",
        *code,
    ]
    # torch and the OpenMP kernels read it at start
    env = {**os.environ, "OMP_NUM_THREADS": str(threads)}
    done = subprocess.run(argv, capture_output=True, text=True, env=env)
    [folder] = out.rglob("seed0")
    if done.returncode != 0:
        raise RuntimeError(f"{method} failed:\n{done.stdout[-2000:]}{done.stderr[-2000:]}")
    results = json.loads((folder / "results.json").read_text())
    if results.get("method_kind") == "official":
        return loop_seconds((folder / "log.txt").read_text()) / iterations
    return float(results["timing"]["train_seconds"]) / iterations


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--ssdgs-code", type=Path, help="SSD-GS checkout at 26e4251 (omit to skip the pair)"
    )
    parser.add_argument(
        "--gs3-code", type=Path, help="GS³ checkout at 83c8daa (omit to skip the pair)"
    )
    parser.add_argument("--python", required=True, help="interpreter of the official environment")
    parser.add_argument("--scene", default="diffuse_shadow")
    parser.add_argument("--iterations", type=int, default=1000)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument(
        "--threads", type=int, default=1, help="threads of every process (default 1)"
    )
    args = parser.parse_args()
    pairs = [
        (native, checkout)
        for native, checkout in (("ssdgs", args.ssdgs_code), ("gs3", args.gs3_code))
        if checkout is not None
    ]
    if not pairs:
        parser.error("give --ssdgs-code and/or --gs3-code")
    print(
        f"# load average at start: {os.getloadavg()[0]:.2f}; {args.iterations} steps of "
        f"{args.scene}, {args.threads} thread(s) per process"
    )
    for native, checkout in pairs:
        code = [
            "--code",
            f"checkout={checkout}",
            "--code",
            f"python={args.python}",
            "--code",
            "device=cpu",
        ]
        ratios = []
        for round_index in range(args.rounds):
            with tempfile.TemporaryDirectory(prefix="bench_official_") as folder:
                native_step = train(
                    native, args.scene, args.iterations, Path(folder, "native"), [], args.threads
                )
                official_step = train(
                    f"{native}-official",
                    args.scene,
                    args.iterations,
                    Path(folder, "official"),
                    code,
                    args.threads,
                )
            ratios.append(official_step / native_step)
            print(
                f"{native} round {round_index}: native {native_step:.4f} s/step, official "
                f"{official_step:.4f} s/step, official/native {ratios[-1]:.2f}x (load "
                f"{os.getloadavg()[0]:.2f})",
                flush=True,
            )
        print(
            f"SUMMARY {native}: official/native median {statistics.median(ratios):.2f}x over "
            f"{args.rounds} round(s)"
        )


if __name__ == "__main__":
    main()
