"""Build-on-first-use of the C++ kernels into a per-user cache, loaded with ctypes.

``SOURCES`` (``csrc/rasterize.cpp``: rasterizer, projection, binning, light pass; ``csrc/ssim.cpp``: the SSIM
training loss; ``csrc/shading.cpp``: SSD-GS's per-Gaussian shading; they include ``HEADERS``: ``csrc/simd.h``, the
vector helpers, ``csrc/rotation.h``, the quaternion conversion, and ``csrc/float_mode.h``, which gives OpenMP
workers the caller's denormal and rounding mode) are compiled by one compiler command into one shared library. It
lives in ``$XDG_CACHE_HOME/olatbench/ext/<hash>/`` (default ``~/.cache``), where ``<hash>`` covers the name and
bytes of every source file and header, the compiler command and the flags, so an edited source or another compiler
gets a fresh build. The compiler is ``$OLATBENCH_CXX``, else ``$CXX``, else ``g++``. Builds are atomic: compile to a
unique temporary name in the same folder, then ``os.replace`` it into place, so several processes may build
concurrently and none ever loads a half-written file.

Flags: ``-O3 -fopenmp -shared -fPIC -std=c++17 -ffp-contract=off``. Deliberately no ``-march=native`` (the
cache may be shared between machines) and no ``-ffast-math`` (the backward must reproduce the forward's
floating-point decisions exactly). If the OpenMP build fails (e.g. Apple clang without libomp), a
single-threaded build without ``-fopenmp`` is tried next (``loaded_path()`` and ``cpu_backend_status()`` say
so); once a single-threaded library is cached it is used without retrying OpenMP (delete the cache to retry).
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shlex
import subprocess
import tempfile
import threading
from pathlib import Path

SOURCES = tuple(Path(__file__).with_name("csrc") / name for name in ("rasterize.cpp", "ssim.cpp", "shading.cpp"))
HEADERS = tuple(Path(__file__).with_name("csrc") / name for name in ("float_mode.h", "rotation.h", "simd.h"))
BASE_FLAGS = ("-O3", "-shared", "-fPIC", "-std=c++17", "-ffp-contract=off")
# Build variants in order of preference.
VARIANTS = {"openmp": (*BASE_FLAGS, "-fopenmp"), "serial": BASE_FLAGS}
LIBRARY_NAME = "olatbench_rasterize.so"
ABI_VERSION = 3


class BuildError(RuntimeError):
    """The C++ kernel library could not be compiled or loaded (message says why and what to do)."""


def compiler() -> list[str]:
    """The compiler command: ``$OLATBENCH_CXX``, else ``$CXX``, else ``g++`` (may contain arguments)."""
    return shlex.split(os.environ.get("OLATBENCH_CXX") or os.environ.get("CXX") or "g++")


def cache_root() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "olatbench" / "ext"


def build_hash(variant: str = "openmp") -> str:
    digest = hashlib.sha256()
    for source in (*SOURCES, *HEADERS):  # name and length delimit each file's bytes
        data = source.read_bytes()
        digest.update(f"{source.name}\0{len(data)}\0".encode())
        digest.update(data)
    digest.update("\0".join([*compiler(), *VARIANTS[variant]]).encode())
    return digest.hexdigest()[:16]


def library_path(variant: str = "openmp") -> Path:
    return cache_root() / build_hash(variant) / LIBRARY_NAME


def compile_variant(variant: str) -> Path:
    """Compile one variant into the cache (atomically) unless present; return its path. Raises BuildError."""
    target = library_path(variant)
    if target.exists():
        return target
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(prefix=".build-", suffix=".so", dir=target.parent)
    except OSError as error:
        raise BuildError(
            f"cannot write the build cache {target.parent}: {error}; point XDG_CACHE_HOME at a writable folder"
        ) from error
    os.close(fd)
    command = [*compiler(), *VARIANTS[variant], *map(str, SOURCES), "-o", tmp_name]
    try:
        result = subprocess.run(command, capture_output=True, text=True, timeout=300)
    except (OSError, subprocess.SubprocessError) as error:
        Path(tmp_name).unlink(missing_ok=True)
        raise BuildError(f"could not run the C++ compiler {shlex.join(command[:1])!r}: {error}") from error
    if result.returncode != 0:
        Path(tmp_name).unlink(missing_ok=True)
        raise BuildError(f"`{shlex.join(command)}` failed (exit {result.returncode}):\n{result.stderr.strip()}")
    os.replace(tmp_name, target)
    return target


def build() -> tuple[Path, str]:
    """The library path and a note ("" for the OpenMP build, else why it is single-threaded), compiling on
    first use. Raises BuildError (with the OpenMP build's error) when no variant builds."""
    if library_path("openmp").exists():
        return library_path("openmp"), ""
    if library_path("serial").exists():
        return library_path("serial"), "single-threaded build (cached; delete it to retry OpenMP)"
    try:
        return compile_variant("openmp"), ""
    except BuildError as openmp_error:
        try:
            path = compile_variant("serial")
        except BuildError:
            raise openmp_error from None
        return path, f"single-threaded build: the OpenMP build failed: {openmp_error}"


_lock = threading.Lock()
_library: ctypes.CDLL | None = None
_path: Path | None = None
_note = ""
_error: BuildError | None = None


def load() -> ctypes.CDLL:
    """The loaded library (built on first use; the outcome is cached for the process). Raises BuildError."""
    global _library, _path, _note, _error
    with _lock:
        if _library is None and _error is None:
            try:
                path, note = build()
                lib = ctypes.CDLL(str(path))
                if lib.olatbench_abi_version() != ABI_VERSION:
                    raise BuildError(f"{path} has an unexpected ABI version")
                _library, _path, _note = lib, path, note
            except BuildError as error:
                _error = error
            except OSError as error:
                _error = BuildError(f"could not load the C++ kernel library: {error}")
        if _error is not None:
            raise _error
        return _library


def loaded_path() -> tuple[Path | None, str]:
    """Path of the loaded library (None before a successful ``load``) and its note (see ``build``)."""
    return _path, _note


def reset() -> None:
    """Forget the cached load outcome (tests use this after changing the compiler environment)."""
    global _library, _path, _note, _error
    with _lock:
        _library, _path, _note, _error = None, None, "", None


__all__ = [
    "BuildError",
    "build",
    "build_hash",
    "cache_root",
    "compile_variant",
    "compiler",
    "library_path",
    "load",
    "loaded_path",
    "reset",
]
