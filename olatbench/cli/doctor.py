"""``olatbench doctor``: what this machine supports, each line with the command that fixes it."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import platform
import tempfile
from collections.abc import Callable
from pathlib import Path

import click

from olatbench.cli.options import json_option

Check = tuple[str, bool, str, str]  # name, ok, detail, fix


def _torch() -> Check:
    if importlib.util.find_spec("torch") is None:
        return (
            "torch",
            False,
            "not installed",
            "pip install torch==2.13.0  (CPU build; pick a CUDA build on a GPU box)",
        )
    import torch

    devices = ["cpu"] + (
        [f"cuda ({torch.cuda.get_device_name(0)})"] if torch.cuda.is_available() else []
    )
    return (
        "torch",
        True,
        f"{torch.__version__}; devices: {', '.join(devices)}; {torch.get_num_threads()} threads",
        "",
    )


# The native libraries (module holding the declaration, what they speed up); without one, torch runs
# instead.
NATIVE_LIBRARIES = (
    ("olatbench.gaussians.backends.cpu", "C++ rasterizer"),  # + projection, binning, light pass
    ("olatbench.metrics.ssim_cpu", "C++ SSIM loss"),
    ("olatbench.methods.ssdgs.shading_cpu", "C++ SSD-GS shading"),
)


def _native_check(module: str, name: str) -> Callable[[], Check]:
    def check() -> Check:
        if importlib.util.find_spec("torch") is None:
            return name, False, "needs torch", "pip install torch==2.13.0"
        ok, detail = importlib.import_module(module).LIBRARY.status()
        if not ok:
            detail = (
                f"unavailable, the slower torch code runs instead (one warning per run): {detail}"
            )
        return (
            name,
            ok,
            detail,
            "" if ok else "apt-get install g++  (with OpenMP; then rerun, the build is cached)",
        )

    check.__name__ = name
    return check


def _cuda() -> Check:
    if importlib.util.find_spec("torch") is None:
        return "CUDA", False, "needs torch", "pip install torch==2.13.0"
    import torch

    if not torch.cuda.is_available():
        build = (
            f"torch built with CUDA {torch.version.cuda}"
            if torch.version.cuda
            else "CPU-only torch build"
        )
        return (
            "CUDA",
            False,
            f"no CUDA device ({build})",
            "on a GPU machine: a CUDA build of torch (pytorch.org)",
        )
    names = ", ".join(
        f"{torch.cuda.get_device_name(i)} "
        f"{torch.cuda.get_device_properties(i).total_memory / 2**30:.0f} GiB"
        for i in range(torch.cuda.device_count())
    )
    return "CUDA", True, f"CUDA {torch.version.cuda}: {names}", ""


def _gsplat() -> Check:
    """gsplat's version and, on a CUDA machine only, whether its extension compiles/loads."""
    if importlib.util.find_spec("torch") is None:
        return "gsplat (CUDA rasterizer)", False, "needs torch", "pip install torch==2.13.0"
    import torch

    from olatbench.gaussians.backends.cuda import gsplat_status, gsplat_version

    ok, detail = gsplat_status()
    if gsplat_version() is None:
        fix = "pip install 'olatbench[cuda]'  (only needed on a GPU)"
    elif not torch.cuda.is_available():
        # nothing to fix on a CPU machine: the extension is compiled on first CUDA use
        ok, fix = True, ""
    else:
        fix = (
            ""
            if ok
            else "install the CUDA toolkit matching torch.version.cuda (nvcc on PATH), then rerun"
        )
    return "gsplat (CUDA rasterizer)", ok, detail, fix


def _stage_backends() -> Check:
    """The backend each training stage will use, on every device present."""
    if importlib.util.find_spec("torch") is None:
        return "Stage backends", False, "needs torch", "pip install torch==2.13.0"
    import torch

    from olatbench.methods.backends import format_backends, stage_backends
    from olatbench.methods.ssdgs.config import SSDGSConfig
    from olatbench.methods.ssdgs.shader import Shader

    shader = Shader(SSDGSConfig())
    lines = []
    for device in ["cpu"] + (["cuda"] if torch.cuda.is_available() else []):
        stages = {**stage_backends(device), "shading": shader.backend_for(device)}
        lines.append(f"{device}: {format_backends(stages)}")
    return "Stage backends (float32)", True, "; ".join(lines), ""


def _bf16_networks() -> Check:
    """Whether bf16 per-Gaussian networks (``network_precision=bf16``) are fast on the devices
    here."""
    if importlib.util.find_spec("torch") is None:
        return "bf16 networks", False, "needs torch", "pip install torch==2.13.0"
    import torch

    from olatbench.methods.shading.precision import fast_bf16_cpu_flag, precision_unsupported

    flag = fast_bf16_cpu_flag()
    lines = [
        f"cpu: fast ({'AMX' if flag == 'amx_tile' else 'AVX512-BF16, no AMX'})"
        if flag
        else f"cpu: not fast ({precision_unsupported('bf16', 'cpu')})"
    ]
    if torch.cuda.is_available():
        reason = precision_unsupported("bf16", "cuda")
        lines.append(
            "cuda: bf16 and fp16 supported" if reason is None else f"cuda: fp16 only ({reason})"
        )
    fast = flag is not None or (
        torch.cuda.is_available() and precision_unsupported("bf16", "cuda") is None
    )
    return (
        "bf16 networks",
        fast,
        "; ".join(lines),
        "" if fast else "nothing to fix: keep network_precision=fp32 (the default)",
    )


def _numerics() -> Check:
    """What decides CPU rounding here, and whether the README's seed-0 figures were measured on this
    CPU."""
    if importlib.util.find_spec("torch") is None:
        return "Numerics (seed-0 figures)", False, "needs torch", "pip install torch==2.13.0"
    from olatbench.numerics import (
        ROUNDING_ENV,
        cpu_label,
        cpu_numerics,
        seed_figure_run,
        seed_figure_runs,
    )

    numerics = cpu_numerics()
    settings = ", ".join(
        f"{name}={numerics[name]}" for name in ROUNDING_ENV if numerics[name] is not None
    )
    detail = (
        f"torch {numerics['torch_cpu_capability']} kernels, {numerics['torch_threads']} threads, "
        f"{settings or 'nothing pinned'}; CPU {cpu_label(numerics['cpu_id'])}"
    )
    run, differences = seed_figure_run(numerics)
    guide = "python benchmarks/numerics_trace.py names where two machines part (docs/runner.md)"
    if run is None:
        checked = "; ".join(cpu_label(other["cpu"]) for other in seed_figure_runs())
        return (
            "Numerics (seed-0 figures)",
            False,
            f"{detail}: not a CPU the README's seed-0 figures were measured on "
            f"({checked}); expect other last digits (README.md)",
            f"nothing to fix: compare runs over seeds; {guide}",
        )
    figures = " / ".join(
        f"{value:.4f}" if value is not None else "?" for value in run["psnr"].values()
    )
    measured = (
        f"the README's seed 0 gave {figures} dB on this CPU ({run['date']}, commit {run['commit']})"
    )
    if differences:
        return (
            "Numerics (seed-0 figures)",
            False,
            f"{detail}: {measured}, but {'; '.join(differences)}: expect other last digits",
            "to compare with those figures, run as that run did (threads: OMP_NUM_THREADS=N; "
            f"a variable: set or unset it); {guide}",
        )
    return (
        "Numerics (seed-0 figures)",
        True,
        f"{detail}: {measured}; expect them to the last digit",
        "",
    )


def _mitsuba() -> Check:
    if importlib.util.find_spec("mitsuba") is None:
        return "Mitsuba (scene generator)", False, "not installed", "pip install 'olatbench[synth]'"
    from olatbench.datasets.synth.backend import probe_variant

    return "Mitsuba (scene generator)", True, f"variant {probe_variant()}", ""


def _lpips() -> Check:
    if importlib.util.find_spec("torch") is None:
        return "LPIPS weights", False, "needs torch", "pip install torch==2.13.0"
    from olatbench.metrics.weights import find_weights

    found = {net: find_weights(net) for net in ("alex", "vgg")}
    missing = [net for net, source in found.items() if source is None]
    detail = "; ".join(
        f"{net}: {source.kind if source else 'missing'}" for net, source in found.items()
    )
    return "LPIPS weights", not missing, detail, "olatbench weights install" if missing else ""


def _exr() -> Check:
    import numpy as np

    from olatbench.datasets.images import read_image, write_image

    with tempfile.TemporaryDirectory() as folder:
        path = write_image(Path(folder) / "probe.exr", np.full((2, 2, 4), 0.25, np.float32))
        ok = bool(np.allclose(read_image(path), 0.25))
    return (
        "EXR read/write (OpenImageIO)",
        ok,
        "round trip ok" if ok else "round trip failed",
        "" if ok else "pip install --force-reinstall OpenImageIO",
    )


def _slurm() -> Check:
    import shutil

    has_submitit = importlib.util.find_spec("submitit") is not None
    has_sbatch = shutil.which("sbatch") is not None
    detail = (
        f"submitit {'installed' if has_submitit else 'missing'}; sbatch "
        f"{'found' if has_sbatch else 'not found'}"
    )
    return (
        "Slurm executor",
        has_submitit,
        detail,
        "" if has_submitit else "pip install 'olatbench[slurm]'",
    )


def _video() -> Check:
    from olatbench.reports.encode import available_encoders

    encoder = available_encoders()[0]
    if encoder != "opencv":
        return "MP4 sweeps (H.264)", True, f"H.264 via {encoder}", ""
    return (
        "MP4 sweeps (H.264)",
        False,
        "only OpenCV mp4v (browsers do not play it)",
        "pip install 'olatbench[video]'",
    )


CHECKS: tuple[Callable[[], Check], ...] = (
    _torch,
    _cuda,
    *(_native_check(module, name) for module, name in NATIVE_LIBRARIES),
    _gsplat,
    _stage_backends,
    _bf16_networks,
    _numerics,
    _mitsuba,
    _lpips,
    _exr,
    _slurm,
    _video,
)


def run_checks() -> list[Check]:
    """Run every check; a check that raises is reported as failed with its error."""
    results = []
    for check in CHECKS:
        try:
            results.append(check())
        except Exception as error:  # a doctor reports, it does not crash
            results.append(
                (check.__name__.strip("_"), False, f"{type(error).__name__}: {error}", "")
            )
    return results


def official_code_checks(code: tuple[str, ...] = ()) -> list[Check]:
    """Checks of each configured official implementation (`olatbench.methods.official.doctor`)."""
    from olatbench.methods.official.doctor import official_checks
    from olatbench.methods.official.settings import SettingsError, parse_code_options
    from olatbench.methods.registry import builtin_specs

    try:
        options = parse_code_options(code)
    except SettingsError as error:
        return [("official implementations", False, str(error), "--code METHOD.KEY=VALUE")]
    return official_checks(builtin_specs(), options)


@click.command()
@click.option(
    "--code",
    multiple=True,
    metavar="METHOD.KEY=VALUE",
    help="Settings of an official implementation to check, over olatbench.toml and the environment "
    "(e.g. gs3-official.checkout=~/src/gs-relight; see docs/official.md).",
)
@click.option(
    "--fake-cuda",
    is_flag=True,
    help="Instead: the fake-CUDA dry run of the GPU path (SSD-GS, GS³, 3DGS under fake CUDA "
    "tensors, no GPU needed): every host sync and device mix of a training step by file:line; "
    "exit 1 when one is not allowed (docs/gpu.md).",
)
@json_option
def doctor(code: tuple[str, ...], fake_cuda: bool, as_json: bool) -> None:
    """Show what this machine supports and how to fix what is missing; what decides CPU rounding
    here and whether the README's seed-0 figures were measured on this CPU; for each configured
    official implementation: its checkout and commit, its interpreter, the GPU it sees.

    \b
    Example:
      olatbench doctor
      olatbench doctor --code gs3-official.checkout=~/src/gs-relight \\
          --code gs3-official.conda_env=gs3
      olatbench doctor --json
      olatbench doctor --fake-cuda      # the GPU path's host syncs and device mixes, on any machine
    """
    if fake_cuda:
        _fake_cuda_dry_run(as_json)
        return
    if as_json:
        checks = [
            {"name": name, "ok": ok, "detail": detail, "fix": fix or None}
            for name, ok, detail, fix in run_checks() + official_code_checks(code)
        ]
        from olatbench.numerics import cpu_numerics

        click.echo(
            json.dumps(
                {
                    "python": platform.python_version(),
                    "machine": platform.machine(),
                    "numerics": cpu_numerics(),
                    "checks": checks,
                },
                indent=2,
            )
        )
        return
    click.echo(f"olatbench on Python {platform.python_version()} ({platform.machine()})")
    for name, ok, detail, fix in run_checks() + official_code_checks(code):
        click.echo(f"  {'ok ' if ok else 'NO '} {name:<32} {detail}")
        if fix:
            click.echo(f"      fix: {fix}")


def _fake_cuda_dry_run(as_json: bool) -> None:
    """Run `olatbench.bench.gpu_dryrun.dry_run`, print its report (or JSON), exit 1 on a violation
    or an error."""
    from olatbench._native import BuildError
    from olatbench.bench.gpu_dryrun import dry_run

    try:
        run = dry_run()
    except (BuildError, ImportError) as error:
        raise click.ClickException(f"the fake-CUDA dry run cannot start: {error}") from None
    if as_json:
        click.echo(
            json.dumps(
                {
                    "log": run.log,
                    "errors": run.errors,
                    "findings": [dataclasses.asdict(f) for f in run.findings],
                    "violations": [dataclasses.asdict(f) for f in run.violations()],
                },
                indent=2,
            )
        )
    else:
        click.echo(run.report())
    if run.violations() or run.errors:
        raise SystemExit(1)
