"""`olatbench doctor` reports every capability and never crashes on a broken one."""

import importlib
import sys
import types

import pytest
import torch
from click.testing import CliRunner

from olatbench.cli import doctor as doctor_module
from olatbench.cli import main


def test_doctor_lists_every_capability():
    result = CliRunner().invoke(main, ["doctor"])
    assert result.exit_code == 0, result.output
    for name in (
        "torch",
        "CUDA",
        "C++ rasterizer",
        "C++ SSIM loss",
        "C++ SSD-GS shading",
        "gsplat",
        "Stage backends",
        "bf16 networks",
        "Numerics (seed-0 figures)",
        "Mitsuba",
        "LPIPS weights",
        "EXR",
        "Slurm",
        "MP4",
    ):
        assert name in result.output


def test_a_missing_native_library_says_torch_runs_instead(monkeypatch, tmp_path):
    libraries = [
        importlib.import_module(module).LIBRARY for module, _ in doctor_module.NATIVE_LIBRARIES
    ]
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setenv("OLATBENCH_CXX", str(tmp_path / "no-such-compiler"))
    for library in libraries:
        library.reset()
    try:
        result = CliRunner().invoke(main, ["doctor"])
    finally:
        for library in libraries:
            library.reset()
    lines = [line for line in result.output.splitlines() if "C++" in line]
    assert len(lines) == 3 and all(
        "NO" in line and "torch code runs instead" in line and "no-such-compiler" in line
        for line in lines
    ), result.output


def test_a_failing_check_is_reported_not_raised(monkeypatch):
    def _broken():
        raise RuntimeError("probe exploded")

    monkeypatch.setattr(doctor_module, "CHECKS", (_broken,))
    result = CliRunner().invoke(main, ["doctor"])
    assert result.exit_code == 0
    assert "NO" in result.output and "probe exploded" in result.output


@pytest.fixture
def fresh_gsplat_status():
    from olatbench.gaussians.backends.cuda import gsplat_status

    gsplat_status.cache_clear()
    yield
    gsplat_status.cache_clear()


def test_without_cuda_gsplat_is_reported_and_not_compiled(fresh_gsplat_status, monkeypatch):
    pytest.importorskip("gsplat")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    monkeypatch.delitem(sys.modules, "gsplat.cuda._backend", raising=False)
    _, ok, detail, fix = doctor_module._gsplat()
    assert ok and fix == "" and "no CUDA device" in detail
    assert detail.startswith(f"gsplat {__import__('gsplat').__version__}")
    assert "gsplat.cuda._backend" not in sys.modules  # the extension build was not attempted


@pytest.mark.parametrize(
    ("extension", "expected"),
    [
        ("loaded", "CUDA extension loaded"),
        (None, "no CUDA toolkit found"),
        ("raises", "failed to build: OSError: nvcc exploded"),
    ],
)
def test_with_cuda_the_extension_build_is_reported(
    fresh_gsplat_status, monkeypatch, extension, expected
):
    """On a GPU machine the check imports gsplat's extension module (which compiles it) and says
    what happened."""
    pytest.importorskip("gsplat")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    if extension == "raises":

        class Exploding(types.ModuleType):
            def __getattr__(self, name):
                raise OSError("nvcc exploded")

        fake = Exploding("gsplat.cuda._backend")
    else:
        fake = types.ModuleType("gsplat.cuda._backend")
        fake._C = None if extension is None else object()
    monkeypatch.setitem(sys.modules, "gsplat.cuda._backend", fake)
    _, ok, detail, fix = doctor_module._gsplat()
    assert expected in detail
    assert ok == (extension == "loaded") and (fix == "") == ok
    from olatbench.gaussians.backends import resolve_backend

    # auto only picks a loadable gsplat
    assert resolve_backend("auto", "cuda") == ("cuda" if ok else "torch")


def test_stage_backends_follow_the_environment(monkeypatch):
    for variable in ("OLATBENCH_RASTERIZER", "OLATBENCH_SSIM", "OLATBENCH_SHADING"):
        monkeypatch.setenv(variable, "torch")
    _, ok, detail, _ = doctor_module._stage_backends()
    assert ok and detail == (
        "cpu: rasterizer=torch, projection=torch, binning=torch, light_pass=torch, ssim=torch, "
        "shading=torch"
    )


@pytest.mark.parametrize(
    ("flags", "expected"),
    [
        (
            ["avx2", "avx512f", "avx512_bf16"],
            "ok  bf16 networks                    cpu: fast (AVX512-BF16, no AMX)",
        ),
        (["avx512_bf16", "amx_tile"], "ok  bf16 networks                    cpu: fast (AMX)"),
        (["avx2"], "NO  bf16 networks                    cpu: not fast (this CPU has neither AMX"),
    ],
)
def test_doctor_says_whether_bf16_is_fast(monkeypatch, flags, expected):
    from olatbench.methods.shading import precision

    monkeypatch.setattr(precision, "cpu_flags", lambda: flags)
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    monkeypatch.setattr(doctor_module, "CHECKS", (doctor_module._bf16_networks,))
    result = CliRunner().invoke(main, ["doctor"])
    assert result.exit_code == 0 and expected in result.output, result.output


def numerics_here(cpu_id: dict, threads: int = 2, **variables) -> dict:
    """cpu_numerics() of a made-up machine: the olatbench pins, ``threads`` torch threads,
    ``variables`` set."""
    from olatbench import numerics

    return {
        "torch_cpu_capability": "AVX2",
        "torch_threads": threads,
        "torch_libraries": {"mkl": None, "onednn": None},
        **dict.fromkeys(numerics.ROUNDING_ENV),
        **numerics.PINS,
        **variables,
        "cpu_id": cpu_id,
        "cpu_flags": ["sse4_2", "avx", "avx2", "fma", "avx512f", "avx512_bf16"],
    }


@pytest.mark.parametrize(
    ("cpu_id", "variables", "expected"),
    [
        (
            {"vendor": "GenuineIntel", "family": 6, "model": 207, "stepping": 2},
            {},
            "ok  Numerics (seed-0 figures)        torch AVX2 kernels, 2 threads, "
            "ATEN_CPU_CAPABILITY=avx2; CPU GenuineIntel family 6 model 207 stepping 2: the "
            "README's seed 0 gave 22.8706 / ",
        ),
        (
            {"vendor": "GenuineIntel", "family": 6, "model": 207, "stepping": 2},
            {"MKL_CBWR": "AVX2"},
            "but MKL_CBWR: AVX2 here, None there: expect other last digits",
        ),
        (
            {"vendor": "GenuineIntel", "family": 6, "model": 143, "stepping": 8},
            {},
            "NO  Numerics (seed-0 figures)        torch AVX2 kernels, 2 threads, "
            "ATEN_CPU_CAPABILITY=avx2; CPU GenuineIntel family 6 model 143 stepping 8: not a CPU "
            "the README's seed-0 figures were measured on (AuthenticAMD family 25;",
        ),
    ],
)
def test_doctor_names_the_numerics_and_whether_the_figures_were_measured_on_this_cpu(
    monkeypatch, cpu_id, variables, expected
):
    from olatbench import numerics

    monkeypatch.setattr(numerics, "cpu_numerics", lambda: numerics_here(cpu_id, **variables))
    monkeypatch.setattr(doctor_module, "CHECKS", (doctor_module._numerics,))
    result = CliRunner().invoke(main, ["doctor"])
    assert result.exit_code == 0 and expected in result.output, result.output
    assert ("fix: nothing to fix" in result.output) == (cpu_id["model"] == 143)
