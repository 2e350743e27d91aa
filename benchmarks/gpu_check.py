"""Check a GPU machine end to end: install, build, CUDA tests, paper-scale benchmark; one JSON and
one Markdown summary.

Run from the repository root on the GPU node (docs/gpu.md gives the steps, also under Slurm)::

    python benchmarks/gpu_check.py -o gpu-check/ --wheels wheels/ --weights weights/

In order, each step's output kept under ``-o DIR``:

1. refuses with exit status 2, before touching anything, when torch sees no CUDA device;
2. ``--wheels DIR``: installs every wheel in DIR with pip, offline (``--no-index --no-deps``; e.g.
   gsplat's pure Python wheel and OpenImageIO, which a bare CUDA image lacks); ``--weights DIR``:
   the LPIPS weights folder (``olatbench weights install -o DIR`` on a machine with internet), used
   through ``$OLATBENCH_WEIGHTS_DIR``;
3. builds the kernels: gsplat's CUDA extension (its JIT build on first use, timed) and olatbench's
   C++ kernels (the CPU side of the comparisons);
4. installs the packaged ``mini`` suite (no Mitsuba needed) and runs ``tests/test_cuda.py`` (marker
   ``cuda``; ``--quick`` leaves out the slow mini training) with a JUnit report;
5. counts the host synchronisations of one SSD-GS training step (``torch.cuda.set_sync_debug_mode``)
   against what the fake-CUDA dry run (``olatbench doctor --fake-cuda``) allows such a step; more
   fails the step;
6. runs ``benchmarks/bench_scale.py --device cuda --analytic`` at the paper's sizes (``--counts``,
   default 100K/300K/550K Gaussians; ``--suites``, default all three; closed-form images of each
   suite's size and count, so no Mitsuba is needed): seconds per step by stage, peak GPU memory, the
   projected time of each suite's schedule and render FPS;
7. writes ``gpu_check.json`` and ``gpu_check.md`` (device, driver, CUDA, torch, gsplat, olatbench,
   date, the test counts, the benchmark table) atomically.

Exit status: 0 when every CUDA test passed and the benchmark ran, 1 when a step failed (the summary
says which and keeps what the others measured), 2 on a usage error or without CUDA.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
NO_CUDA = 2


def cuda_refusal() -> str | None:
    """Why this machine cannot run the check (no torch, a CPU-only torch build, no visible device),
    or None."""
    try:
        import torch
    except ImportError:
        return "torch is not installed: install a CUDA build of torch first (docs/gpu.md)"
    if torch.version.cuda is None:
        return (
            f"torch {torch.__version__} is a CPU-only build: install a CUDA build on the GPU node "
            "(docs/gpu.md)"
        )
    if not torch.cuda.is_available():
        return (
            f"torch {torch.__version__} (CUDA {torch.version.cuda}) sees no CUDA device: run this "
            "on a GPU node (under Slurm: srun --gpus-per-node=1 ...; docs/gpu.md)"
        )
    return None


def run_logged(command: list[str], log: Path, timeout: float | None = None) -> tuple[int, float]:
    """Run ``command`` from the repository root, with this checkout first on its ``PYTHONPATH``
    (olatbench need not be installed on the node), and its output in ``log``;
    (exit status, seconds)."""
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])),
    }
    clock = time.perf_counter()
    with log.open("w") as out:
        print("$", " ".join(command), file=out, flush=True)
        try:
            done = subprocess.run(
                command, cwd=REPO, stdout=out, stderr=subprocess.STDOUT, env=env, timeout=timeout
            )
            code = done.returncode
        except subprocess.TimeoutExpired:
            print(f"timed out after {timeout} s", file=out)
            code = 124
    return code, time.perf_counter() - clock


def install_wheels(wheels: Path, out: Path) -> dict:
    found = sorted(wheels.glob("*.whl"))
    if not found:
        raise SystemExit(f"--wheels {wheels}: no .whl files there")
    command = [sys.executable, "-m", "pip", "install", "--no-index", "--no-deps", *map(str, found)]
    code, seconds = run_logged(command, out / "install.log")
    return {"wheels": [w.name for w in found], "exit_code": code, "seconds": round(seconds, 1)}


def environment() -> dict:
    """Device, driver, CUDA, torch, gsplat and olatbench versions, and the date."""
    import torch

    from olatbench import __version__
    from olatbench.gaussians.backends.cuda import gsplat_version

    def command_output(command: list[str]) -> str | None:
        try:
            return (
                subprocess.run(command, capture_output=True, text=True, timeout=60).stdout.strip()
                or None
            )
        except (OSError, subprocess.TimeoutExpired):
            return None

    props = torch.cuda.get_device_properties(0)
    commit = command_output(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"])
    return {
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "device": props.name,
        "device_memory_gib": round(props.total_memory / 2**30, 1),
        "multiprocessors": props.multi_processor_count,
        "driver": command_output(
            ["nvidia-smi", "--query-gpu=driver_version", "--format=csv,noheader"]
        ),
        "cuda": torch.version.cuda,
        "torch": torch.__version__,
        "gsplat": gsplat_version(),
        "olatbench": __version__,
        "commit": commit,
        "python": platform.python_version(),
        "nvcc": (command_output(["nvcc", "--version"]) or "").splitlines()[-1:] or None,
    }


def build_kernels() -> dict:
    """gsplat's CUDA extension (JIT-built on first use) and olatbench's C++ libraries, each with its
    status."""
    from olatbench.gaussians.backends import cpu_backend_status
    from olatbench.gaussians.backends.cuda import gsplat_status

    clock = time.perf_counter()
    usable, detail = gsplat_status()
    built = {
        "gsplat": {"ok": usable, "detail": detail, "seconds": round(time.perf_counter() - clock, 1)}
    }
    ok, detail = cpu_backend_status()
    built["olatbench_cpp"] = {"ok": ok, "detail": detail}
    return built


def junit_counts(report: Path) -> dict:
    """Passed, failed, errors and skipped of a pytest JUnit XML report."""
    if not report.exists():
        return {"passed": 0, "failed": 0, "errors": 0, "skipped": 0, "report": None}
    suite = ET.parse(report).getroot()
    suite = suite if suite.tag == "testsuite" else suite.find("testsuite")
    total, failed, errors, skipped = (
        int(suite.get(key, 0)) for key in ("tests", "failures", "errors", "skipped")
    )
    return {
        "passed": total - failed - errors - skipped,
        "failed": failed,
        "errors": errors,
        "skipped": skipped,
        "report": report.name,
    }


def run_cuda_tests(out: Path, quick: bool) -> dict:
    code, seconds = run_logged(
        [sys.executable, "-m", "olatbench", "datasets", "synth", "--mini", "-q"],
        out / "mini_install.log",
    )
    if code != 0:
        return {"exit_code": code, "step": "mini install", "log": "mini_install.log"}
    marker = "cuda and not slow" if quick else "cuda"
    report = out / "cuda_tests.xml"
    code, seconds = run_logged(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-rA",
            "-p",
            "no:cacheprovider",
            "-m",
            marker,
            "tests/test_cuda.py",
            f"--junitxml={report}",
        ],
        out / "cuda_tests.log",
    )
    return {
        "exit_code": code,
        "marker": marker,
        "seconds": round(seconds, 1),
        **junit_counts(report),
        "log": "cuda_tests.log",
    }


def count_step_syncs() -> dict:
    """Host synchronisations in one SSD-GS training step on a small closed-form scene (steady state:
    the second of two steps), counted as the warnings of
    ``torch.cuda.set_sync_debug_mode("warn")``."""
    import warnings

    import numpy as np
    import torch

    from olatbench.datasets.synth.analytic import render_sphere, sphere_rig
    from olatbench.methods.base import Views
    from olatbench.methods.ssdgs import SSDGS

    cameras, lights = sphere_rig(4, 64)
    views = Views(
        cameras=cameras,
        lights=lights,
        images=np.stack([render_sphere(c, lt) for c, lt in zip(cameras, lights, strict=True)]),
        frame_ids=["0", "1", "2", "3"],
        background=np.zeros(3, dtype=np.float32),
        scene_name="sphere",
    )
    method = SSDGS(SSDGS.resolve_config("mini", iterations=1000, num_init_gaussians=5000))
    method.setup(views, "cuda", 0)
    method.train_step(998)
    torch.cuda.synchronize()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        torch.cuda.set_sync_debug_mode("warn")
        try:
            method.train_step(999)
        finally:
            torch.cuda.set_sync_debug_mode("default")
    syncs = [str(w.message).splitlines()[0] for w in caught if "synchroniz" in str(w.message)]
    return {"syncs_per_step": len(syncs), "first": syncs[:5], **dry_run_expectation()}


def dry_run_expectation() -> dict:
    """What the fake-CUDA dry run (`olatbench.bench.gpu_dryrun`) finds for SSD-GS's ``mini`` preset,
    the step `count_step_syncs` measures: its violations (none expected) and the syncs it allows in
    its last step, one that neither densifies nor logs with the shadow term on (one
    tile-intersection count per rasterization pass, the light pass's entry layout): the number a
    real step should not exceed."""
    from olatbench.bench.gpu_dryrun import dry_run

    run = dry_run((("ssdgs mini", "ssdgs", "mini", {"shadow_resolution": 16}),))
    steps = [f.phase for f in run.findings if f.phase.startswith("ssdgs mini: train_step")]
    last = steps[-1] if steps else None
    return {
        "dry_run_allowed_per_step": sum(f.phase == last for f in run.findings),
        "dry_run_violations": [f.line() for f in run.violations()] + run.errors,
    }


def run_benchmark(out: Path, suites: list[str], counts: list[int], steps: int) -> dict:
    result = out / "bench_scale.json"
    code, seconds = run_logged(
        [
            sys.executable,
            "benchmarks/bench_scale.py",
            "--device",
            "cuda",
            "--analytic",
            "--suites",
            *suites,
            "--counts",
            *map(str, counts),
            "--steps",
            str(steps),
            "--json",
            str(result),
        ],
        out / "bench_scale.log",
    )
    cases = json.loads(result.read_text())["cases"] if result.exists() else []
    return {
        "exit_code": code,
        "seconds": round(seconds, 1),
        "cases": cases,
        "log": "bench_scale.log",
    }


def markdown(summary: dict) -> str:
    """The summary as the Markdown docs/gpu.md quotes."""
    env, tests = summary["environment"], summary.get("cuda_tests", {})
    lines = [
        f"# GPU check, {env['date']}",
        "",
        f"{env['device']} ({env['device_memory_gib']} GiB), driver {env['driver']}, CUDA "
        f"{env['cuda']}, torch {env['torch']}, gsplat {env['gsplat']}, olatbench "
        f"{env['olatbench']} ({env['commit']})",
        "",
        f"CUDA tests ({tests.get('marker')}): {tests.get('passed', 0)} passed, "
        f"{tests.get('failed', 0)} failed, {tests.get('errors', 0)} errors, "
        f"{tests.get('skipped', 0)} skipped",
        "",
    ]
    syncs = summary.get("syncs", {})
    if "syncs_per_step" in syncs:
        lines += [
            f"Host synchronisations in one SSD-GS training step: {syncs['syncs_per_step']} (the "
            f"fake-CUDA dry run allows {syncs['dry_run_allowed_per_step']}; its violations: "
            f"{len(syncs['dry_run_violations'])})",
            "",
        ]
    cases = summary.get("benchmark", {}).get("cases", [])
    if cases:
        lines += [
            "| suite | size | images | Gaussians | s/step | raster | light pass | networks | Adam "
            "| rest | peak GPU GiB | projected schedule | render FPS |",
            "|" + "---|" * 13,
        ]
        for case in cases:
            stages = case["stages"]
            lines.append(
                f"| {case['suite']} | {case['width']}×{case['height']} | {case['images']} | "
                f"{case['gaussians']} | {case['step_seconds']:.3f} | {stages['raster']:.3f} | "
                f"{stages['shadow']:.3f} | {stages['mlp']:.3f} | {stages['optim']:.3f} | "
                f"{stages['rest']:.3f} | {case['peak_device_gib']:.2f} | "
                f"{case['projected_seconds'] / 3600:.2f} h | {case['render_fps']:.1f} |"
            )
    failed = summary.get("failed_steps")
    if failed:
        lines += ["", f"Failed steps: {', '.join(failed)} (logs beside this file)"]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "-o", "--output", required=True, type=Path, help="folder for the summaries and logs"
    )
    parser.add_argument(
        "--wheels", type=Path, help="folder of wheels to install offline first (gsplat, ...)"
    )
    parser.add_argument(
        "--weights", type=Path, help="folder holding lpips_alex.pt (olatbench weights install)"
    )
    parser.add_argument(
        "--quick", action="store_true", help="no mini training; 100K Gaussians only"
    )
    parser.add_argument("--suites", nargs="+", default=["nrhints", "gs3", "sssgs"])
    parser.add_argument(
        "--counts",
        type=int,
        nargs="+",
        default=None,
        help="Gaussian counts of the benchmark (default 100000 300000 550000; --quick: 100000)",
    )
    parser.add_argument(
        "--steps", type=int, default=5, help="timed training steps per benchmark case"
    )
    args = parser.parse_args(argv)
    refusal = cuda_refusal()
    if refusal is not None:
        print(f"gpu_check: {refusal}", file=sys.stderr)
        return NO_CUDA
    if args.weights is not None:
        os.environ["OLATBENCH_WEIGHTS_DIR"] = str(args.weights.resolve())
    out = args.output
    out.mkdir(parents=True, exist_ok=True)
    summary: dict = {"failed_steps": []}
    if args.wheels is not None:
        summary["install"] = install_wheels(args.wheels, out)
        if summary["install"]["exit_code"] != 0:
            summary["failed_steps"].append("install")
    summary["environment"] = environment()
    summary["build"] = build_kernels()
    if not summary["build"]["gsplat"]["ok"]:
        summary["failed_steps"].append("gsplat build")
    summary["cuda_tests"] = run_cuda_tests(out, args.quick)
    if summary["cuda_tests"]["exit_code"] != 0:
        summary["failed_steps"].append("CUDA tests")
    try:
        summary["syncs"] = count_step_syncs()
        syncs = summary["syncs"]
        if (
            syncs["dry_run_violations"]
            or syncs["syncs_per_step"] > syncs["dry_run_allowed_per_step"]
        ):
            # more than the dry run allows: it missed one
            summary["failed_steps"].append("sync count")
    except Exception as error:  # reported in the summary with the others' results, not lost
        summary["syncs"] = {"error": f"{type(error).__name__}: {error}"}
        summary["failed_steps"].append("sync count")
    counts = args.counts or ([100_000] if args.quick else [100_000, 300_000, 550_000])
    summary["benchmark"] = run_benchmark(out, args.suites, counts, args.steps)
    if summary["benchmark"]["exit_code"] != 0:
        summary["failed_steps"].append("benchmark")
    from olatbench.atomic import write_json, write_text

    write_json(out / "gpu_check.json", summary)
    write_text(out / "gpu_check.md", markdown(summary))
    print(markdown(summary))
    return 1 if summary["failed_steps"] else 0


if __name__ == "__main__":
    sys.path.insert(0, str(REPO))
    raise SystemExit(main())
