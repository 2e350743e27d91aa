"""olatbench._native: build keys (content, machine, OS, compiler), one compile under parallel
builders, typed symbol tables, the ABI check, each owner's own library, and the one backend-choice
rule."""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import pytest
from waiting import BACKSTOP_SECONDS

from olatbench import _native
from olatbench._native import NativeLibrary, Signature, Unavailable, always, build, choose_backend
from olatbench.gaussians.backends.cpu import LIBRARY as GAUSSIANS
from olatbench.methods.ssdgs.shading_cpu import LIBRARY as SHADING
from olatbench.metrics.ssim_cpu import LIBRARY as SSIM

PACKAGE = Path(_native.__file__).resolve().parents[1]
LIBRARIES = (GAUSSIANS, SSIM, SHADING)
TINY_SOURCE = """\
#include <cstdint>
#include "export.h"
OLATBENCH_EXPORT int64_t tiny_add(int64_t a, double b) { return a + static_cast<int64_t>(b); }
OLATBENCH_DEFINE_ABI_VERSION()
"""
TINY_SYMBOLS = {"tiny_add": Signature(ctypes.c_int64, (ctypes.c_int64, ctypes.c_double))}


@pytest.fixture
def cache(monkeypatch, tmp_path):
    """An empty build cache, the default compiler."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv("OLATBENCH_CXX", raising=False)
    monkeypatch.delenv("CXX", raising=False)
    return tmp_path


def tiny_library(folder: Path, source: str = TINY_SOURCE, symbols=None) -> NativeLibrary:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "tiny.cpp").write_text(source)
    return NativeLibrary(
        "tiny", [folder / "tiny.cpp"], TINY_SYMBOLS if symbols is None else symbols
    )


def logging_compiler(folder: Path, delay_s: float = 0.0) -> Path:
    """A g++ wrapper that appends one line to ``compiles.log`` per compilation
    (not per --version query)."""
    script = folder / "logging-g++"
    script.write_text(
        textwrap.dedent(f"""\
        #!/bin/sh
        case " $* " in *" -o "*) echo "$$" >> "{folder / "compiles.log"}"; sleep {delay_s};; esac
        exec g++ "$@"
        """)
    )
    script.chmod(0o755)
    return script


def compiles(folder: Path) -> int:
    log = folder / "compiles.log"
    return len(log.read_text().splitlines()) if log.exists() else 0


# Build keys ---------------------------------------------------------------------------------------


def test_the_key_names_machine_and_os(cache, monkeypatch):
    library = tiny_library(cache / "src")
    keys = {
        tag: build.build_key("tiny", library.sources, machine=tag)
        for tag in ("x86_64-linux", "aarch64-linux", "x86_64-darwin", "arm64-darwin")
    }
    assert len(set(keys.values())) == len(keys)  # every architecture and OS its own build
    assert build.platform_tag() == f"{__import__('platform').machine()}-{sys.platform}"
    here = library.path()
    monkeypatch.setattr(build.platform, "machine", lambda: "riscv64")
    elsewhere = library.path()
    # same shared cache, other folder
    assert elsewhere != here and elsewhere.parent.parent == here.parent.parent
    monkeypatch.setattr(build.sys, "platform", "darwin")
    assert library.path() not in (here, elsewhere)


def test_the_key_names_the_compiler_and_its_version(cache, monkeypatch):
    library = tiny_library(cache / "src")
    before = library.path()
    for version in ("fake 1.0", "fake 2.0"):
        script = cache / f"cxx-{version.split()[1]}"
        script.write_text(
            f'#!/bin/sh\n[ "$1" = --version ] && {{ echo "{version}"; exit 0; }}\nexec g++ "$@"\n'
        )
        script.chmod(0o755)
    monkeypatch.setenv("OLATBENCH_CXX", str(cache / "cxx-1.0"))
    one = library.path()
    (cache / "cxx-1.0").write_text((cache / "cxx-2.0").read_text())  # same command, another version
    build.compiler_version.cache_clear()
    two = library.path()
    build.compiler_version.cache_clear()
    assert len({before, one, two}) == 3


def test_the_key_covers_every_source_and_header(cache, monkeypatch):
    """Each real library's key changes with each file it compiles or may include, and with nothing
    else."""
    copy = cache / "olatbench"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("*.py", "__pycache__"))
    monkeypatch.setattr(build, "INCLUDE_DIR", copy / "_native" / "include")
    moved = [
        NativeLibrary(
            lib.name,
            [copy / s.relative_to(PACKAGE) for s in lib.sources],
            {},
            [copy / d.relative_to(PACKAGE) for d in lib.include_dirs],
        )
        for lib in LIBRARIES
    ]
    files = sorted({*copy.rglob("*.cpp"), *copy.rglob("*.h")})
    assert {f.name for f in files} >= {
        "rasterize.cpp",
        "ssim.cpp",
        "shading.cpp",
        "rotation.h",
        "simd.h",
        "float_mode.h",
        "export.h",
    }
    needs = {
        "olatbench_gaussians": {
            "rasterize.cpp",
            "rotation.h",
            "simd.h",
            "float_mode.h",
            "export.h",
        },
        "olatbench_ssim": {"ssim.cpp", "simd.h", "float_mode.h", "export.h"},
        "olatbench_ssdgs_shading": {
            "shading.cpp",
            "rotation.h",
            "simd.h",
            "float_mode.h",
            "export.h",
        },
    }
    for edited in files:
        before = {lib.name: lib.path() for lib in moved}
        edited.write_text(edited.read_text() + "\n// edited\n")
        changed = {lib.name for lib in moved if lib.path() != before[lib.name]}
        assert changed == {name for name, names in needs.items() if edited.name in names}, (
            edited.name
        )


def test_editing_the_ssdgs_shading_kernel_does_not_rebuild_the_rasterizer(cache):
    """Issue #21's check on the real declarations: shading.cpp is SSD-GS's alone."""
    copy = cache / "olatbench"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("*.py", "__pycache__"))

    def moved(lib: NativeLibrary) -> NativeLibrary:
        return NativeLibrary(
            lib.name,
            [copy / s.relative_to(PACKAGE) for s in lib.sources],
            {},
            [copy / d.relative_to(PACKAGE) for d in lib.include_dirs],
        )

    rasterizer, shading = moved(GAUSSIANS), moved(SHADING)
    before = rasterizer.path(), shading.path()
    source = copy / "methods" / "ssdgs" / "csrc" / "shading.cpp"
    source.write_text(
        source.read_text().replace(
            "constexpr double kSmoothAlpha = 0.01;", "constexpr double kSmoothAlpha = 0.02;"
        )
    )
    assert rasterizer.path() == before[0]
    assert shading.path() != before[1]


# Building -----------------------------------------------------------------------------------------


def test_parallel_builders_compile_once(cache, monkeypatch):
    """Two processes load the same cold library at once: one compiles, the other waits for it
    (file lock)."""
    tiny_library(cache / "src")
    monkeypatch.setenv("OLATBENCH_CXX", str(logging_compiler(cache, delay_s=2.0)))
    program = textwrap.dedent(f"""\
        import ctypes, sys
        from olatbench._native import NativeLibrary, Signature
        lib = NativeLibrary("tiny", [{str(cache / "src" / "tiny.cpp")!r}],
                            {{"tiny_add": Signature(ctypes.c_int64, (ctypes.c_int64, ctypes.c_double))}})
        print(lib.load()["tiny_add"](40, 2.5))
        """)  # noqa: E501
    env = {**__import__("os").environ, "PYTHONPATH": str(PACKAGE.parent)}
    workers = [
        subprocess.Popen(
            [sys.executable, "-c", program],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        for _ in range(2)
    ]
    outputs = [worker.communicate(timeout=BACKSTOP_SECONDS) for worker in workers]
    for worker, (out, err) in zip(workers, outputs, strict=True):
        assert worker.returncode == 0, err
        assert out.strip() == "42"
    assert compiles(cache) == 1
    # the temporary file was renamed into place
    assert not list((cache / "cache").rglob(".build-*"))


def test_a_built_library_is_reused(cache, monkeypatch):
    monkeypatch.setenv("OLATBENCH_CXX", str(logging_compiler(cache)))
    first = tiny_library(cache / "src")
    assert first.load()["tiny_add"](1, 2.0) == 3
    again = tiny_library(cache / "src")  # a new process would see the same: the cached file
    assert again.load().path == first.load().path and compiles(cache) == 1


# Typed symbol tables and the ABI ------------------------------------------------------------------


def test_symbols_are_typed_once_and_only_declared_ones_are_callable(cache):
    lib = tiny_library(cache / "src").load()
    assert lib["tiny_add"](2**40, 3.9) == 2**40 + 3  # int64 in and out, double argument converted
    with pytest.raises(TypeError):
        lib["tiny_add"](1)  # wrong argument count: refused by ctypes, not passed as garbage
    with pytest.raises(ctypes.ArgumentError):
        lib["tiny_add"]("1", 2.0)
    with pytest.raises(KeyError, match="not in the symbol table"):
        lib["olatbench_abi_versionX"]


def test_a_declared_symbol_the_library_lacks_is_a_build_error(cache):
    library = tiny_library(cache / "src", symbols={**TINY_SYMBOLS, "tiny_sub": Signature(None, ())})
    ok, detail = library.status()
    assert not ok and "does not export tiny_sub" in detail


def test_the_abi_version_is_checked(cache):
    source = (
        'extern "C" __attribute__((visibility("default"))) int olatbench_abi_version() { return '
        "1; }\n"
    )
    ok, detail = tiny_library(cache / "src", source=source, symbols={}).status()
    assert not ok and f"ABI version 1, expected {build.ABI_VERSION}" in detail


def test_every_export_of_the_real_libraries_is_in_its_table():
    if shutil.which("nm") is None:
        pytest.skip("nm not installed")
    for library in LIBRARIES:
        ok, detail = library.status()
        if not ok:
            pytest.skip(f"{library.name} unavailable: {detail}")
        listing = subprocess.run(
            ["nm", "-D", "--defined-only", str(library.load().path)],
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        exported = {line.split()[-1] for line in listing.splitlines() if " T olatbench_" in line}
        assert exported == {"olatbench_abi_version", *library.symbols}, library.name


# choose_backend -----------------------------------------------------------------------------------


def missing() -> Unavailable:
    return Unavailable("not built (no compiler)", missing=True)


def unsuited() -> Unavailable:
    return Unavailable("it supports float32 only")


@pytest.fixture
def fresh_warnings():
    _native.reset_fallback_warnings()
    yield
    _native.reset_fallback_warnings()


def test_auto_takes_the_first_backend_that_can_run(fresh_warnings):
    calls = []

    def counted(result):
        def check():
            calls.append(result)
            return result

        return check

    assert (
        choose_backend(
            "auto", "cpu", {"cuda": counted(None), "cpu": counted(None), "torch": always}, kind="k"
        )
        == "cpu"
    )
    assert calls == [None]  # the cuda check never ran for CPU tensors
    assert (
        choose_backend("auto", "cuda", {"cuda": always, "cpu": always, "torch": always}, kind="k")
        == "cuda"
    )
    assert (
        choose_backend("auto", "mps", {"cuda": always, "cpu": always, "torch": always}, kind="k")
        == "torch"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # unsuited inputs are passed over silently
        assert (
            choose_backend("auto", "cpu", {"cpu": unsuited, "torch": always}, kind="k") == "torch"
        )


def test_a_missing_backend_falls_back_with_one_warning(fresh_warnings):
    with pytest.warns(
        RuntimeWarning,
        match=r"the k backend 'cpu' is unavailable, falling back to 'torch'. "
        r"Reason: not built \(no compiler\)\nSet K_ENV=torch",
    ):
        assert (
            choose_backend(
                "auto", "cpu", {"cpu": missing, "torch": always}, kind="k", env_var="K_ENV"
            )
            == "torch"
        )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # once per process and resolver
        assert choose_backend("auto", "cpu", {"cpu": missing, "torch": always}, kind="k") == "torch"
    with pytest.warns(RuntimeWarning, match="the other backend 'cpu'"):
        choose_backend("auto", "cpu", {"cpu": missing, "torch": always}, kind="other")


def test_explicit_requests_run_as_asked_or_fail(fresh_warnings):
    available = {"cuda": always, "cpu": unsuited, "torch": always}
    assert choose_backend("torch", "cuda", available, kind="k") == "torch"
    with pytest.raises(
        ValueError, match="k backend 'cpu' cannot run these inputs: it supports float32 only"
    ):
        choose_backend("cpu", "cpu", available, kind="k")
    with pytest.raises(ValueError, match="it needs CUDA tensors, got cpu"):
        choose_backend("cuda", "cpu", available, kind="k")
    with pytest.raises(RuntimeError, match="k backend 'cpu' is unavailable: not built"):
        choose_backend("cpu", "cpu", {"cpu": missing, "torch": always}, kind="k")
    with pytest.raises(
        ValueError, match="unknown k backend 'gpu'; choose one of cuda, cpu, torch or 'auto'"
    ):
        choose_backend("gpu", "cpu", available, kind="k")


def test_the_environment_variable_replaces_auto_only(fresh_warnings, monkeypatch):
    available = {"cpu": always, "torch": always}
    monkeypatch.setenv("K_ENV", " Torch ")
    assert choose_backend("auto", "cpu", available, kind="k", env_var="K_ENV") == "torch"
    assert choose_backend("cpu", "cpu", available, kind="k", env_var="K_ENV") == "cpu"
    # a resolver without the variable
    assert choose_backend("auto", "cpu", available, kind="k") == "cpu"
    monkeypatch.setenv("K_ENV", "banana")
    with pytest.raises(
        ValueError, match="'banana' \\(from the environment variable K_ENV='banana'\\)"
    ):
        choose_backend("auto", "cpu", available, kind="k", env_var="K_ENV")
