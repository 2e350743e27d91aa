"""Compile C++ sources into a shared library in a per-user cache, once per content and machine.

A library is ``<cache>/<name>-<key>/<name>.so`` with ``<cache>`` = ``$XDG_CACHE_HOME/olatbench/ext``
(default ``~/.cache``). The key (``build_key``) is a hash of everything that decides the binary: the
library name, the name and bytes of every source and of every header (``*.h``) in the sources'
folders and in the include folders, the compiler command and its ``--version`` text, the flags
(with ``ABI_VERSION``), the machine architecture (``platform.machine()``) and the OS
(``sys.platform``). So an edited source, another compiler or another machine sharing the cache gets
its own build, and editing one owner's C++ rebuilds only its library.

The compiler is ``$OLATBENCH_CXX``, else ``$CXX``, else ``g++``. Flags: ``-O3 -fopenmp -shared -fPIC
-std=c++17 -ffp-contract=off`` plus ``-DOLATBENCH_ABI_VERSION`` and ``-I`` for each include folder.
Deliberately no ``-march=native`` (the vectorised loops carry an AVX2 copy chosen at run time) and
no ``-ffast-math`` (the backwards must reproduce their forwards' floating-point decisions exactly).
If the OpenMP build fails (e.g. Apple clang without libomp), a single-threaded build without
``-fopenmp`` is tried next, and its note says so; once a single-threaded library is cached it is
used without retrying OpenMP (delete it to retry).

Concurrency: a build holds an exclusive ``fcntl.flock`` on ``<name>-<key>.lock`` in the cache
folder, so parallel workers (``olatbench run --jobs N``) compile once and the others wait for that
build; the compiler writes a unique temporary file that ``os.replace`` moves into place, so no
process ever loads a half-written library.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import platform
import shlex
import subprocess
import sys
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path

try:
    import fcntl
except ImportError:  # not POSIX: builds are then only protected by the atomic rename
    fcntl = None

# Version of the conventions every library shares (include/export.h: C symbols on raw pointers, the
# olatbench_abi_version() check). Passed to the compiler, so it is part of every build key: bump it
# to rebuild all libraries.
ABI_VERSION = 4
# export.h, simd.h, float_mode.h: on every library's path
INCLUDE_DIR = Path(__file__).with_name("include")
BASE_FLAGS = (
    "-O3",
    "-shared",
    "-fPIC",
    "-std=c++17",
    "-ffp-contract=off",
    f"-DOLATBENCH_ABI_VERSION={ABI_VERSION}",
)
VARIANTS = {"openmp": (*BASE_FLAGS, "-fopenmp"), "serial": BASE_FLAGS}  # in order of preference
COMPILE_TIMEOUT_S = 300


class BuildError(RuntimeError):
    """A native library could not be compiled or loaded (the message says why and what to do)."""


def compiler() -> list[str]:
    """The compiler command: ``$OLATBENCH_CXX``, else ``$CXX``, else ``g++``
    (may contain arguments)."""
    return shlex.split(os.environ.get("OLATBENCH_CXX") or os.environ.get("CXX") or "g++")


@functools.lru_cache(maxsize=8)
def compiler_version(command: tuple[str, ...]) -> str:
    """``command --version`` (stdout and stderr), or why it could not run: part of the build key."""
    try:
        result = subprocess.run([*command, "--version"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.SubprocessError) as error:
        return f"unavailable: {error}"
    return f"exit {result.returncode}\n{result.stdout}{result.stderr}"


def platform_tag() -> str:
    """``<machine>-<os>``, e.g. ``x86_64-linux``: libraries of one tag never load on another."""
    return f"{platform.machine()}-{sys.platform}"


def cache_root() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "olatbench" / "ext"


def include_dirs(extra: Sequence[Path] = ()) -> tuple[Path, ...]:
    """The include folders of a build: the shared ``include/`` first, then ``extra``."""
    return (INCLUDE_DIR, *extra)


def key_files(sources: Sequence[Path], extra_includes: Sequence[Path] = ()) -> list[Path]:
    """The files a build depends on: the sources, then every ``*.h`` of their folders and the
    include folders (sorted, each once)."""
    folders = dict.fromkeys([*(Path(s).parent for s in sources), *include_dirs(extra_includes)])
    headers = sorted({header for folder in folders for header in Path(folder).glob("*.h")})
    return [*map(Path, sources), *headers]


def build_key(
    name: str,
    sources: Sequence[Path],
    extra_includes: Sequence[Path] = (),
    variant: str = "openmp",
    *,
    machine: str | None = None,
) -> str:
    """16 hex digits naming one build (see the module docstring). ``machine`` replaces
    ``platform_tag()``."""
    digest = hashlib.sha256()
    command = compiler()
    parts = [
        name,
        machine or platform_tag(),
        *command,
        compiler_version(tuple(command)),
        *VARIANTS[variant],
    ]
    digest.update("\0".join(parts).encode())
    for path in key_files(sources, extra_includes):  # name and length delimit each file's bytes
        data = path.read_bytes()
        digest.update(f"\0{path.name}\0{len(data)}\0".encode())
        digest.update(data)
    return digest.hexdigest()[:16]


def library_path(
    name: str, sources: Sequence[Path], extra_includes: Sequence[Path] = (), variant: str = "openmp"
) -> Path:
    key = build_key(name, sources, extra_includes, variant)
    return cache_root() / f"{name}-{key}" / f"{name}.so"


@contextlib.contextmanager
def build_lock(target: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``<target folder>.lock`` (blocks until other builders release
    it)."""
    with open(target.parent.with_name(target.parent.name + ".lock"), "a") as handle:
        if fcntl is not None:
            fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            if fcntl is not None:
                fcntl.flock(handle, fcntl.LOCK_UN)


def compile_variant(
    name: str, sources: Sequence[Path], extra_includes: Sequence[Path] = (), variant: str = "openmp"
) -> Path:
    """Compile one variant into the cache unless present; return its path. Raises BuildError."""
    target = library_path(name, sources, extra_includes, variant)
    if target.exists():
        return target
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with build_lock(target):
            if not target.exists():  # another process may have built it while this one waited
                _compile(sources, extra_includes, variant, target)
    except OSError as error:
        raise BuildError(
            f"cannot write the build cache {target.parent}: {error}; point XDG_CACHE_HOME at a "
            "writable folder"
        ) from error
    return target


def _compile(
    sources: Sequence[Path], extra_includes: Sequence[Path], variant: str, target: Path
) -> None:
    flags = [*VARIANTS[variant], *(f"-I{folder}" for folder in include_dirs(extra_includes))]
    compile_library([*flags, *map(str, sources)], target)


def compile_library(arguments: Sequence[str], target: Path) -> None:
    """Run the C++ compiler (`compiler`) with ``arguments`` (flags and sources) into a temporary
    file beside ``target`` and move it into place atomically; a `BuildError` with the command and
    the compiler's message when it cannot run or fails (nothing is left behind)."""
    fd, tmp_name = tempfile.mkstemp(prefix=".build-", suffix=".so", dir=target.parent)
    os.close(fd)
    command = [*compiler(), *arguments, "-o", tmp_name]
    try:
        result = subprocess.run(command, capture_output=True, text=True, timeout=COMPILE_TIMEOUT_S)
    except (OSError, subprocess.SubprocessError) as error:
        Path(tmp_name).unlink(missing_ok=True)
        raise BuildError(
            f"could not run the C++ compiler {shlex.join(command[:1])!r}: {error}"
        ) from error
    if result.returncode != 0:
        Path(tmp_name).unlink(missing_ok=True)
        raise BuildError(
            f"`{shlex.join(command)}` failed (exit {result.returncode}):\n{result.stderr.strip()}"
        )
    os.replace(tmp_name, target)


def build(
    name: str, sources: Sequence[Path], extra_includes: Sequence[Path] = ()
) -> tuple[Path, str]:
    """The library path and a note ("" for the OpenMP build, else why it is single-threaded),
    compiling on first use. Raises BuildError (with the OpenMP build's error) when no variant
    builds."""
    openmp = library_path(name, sources, extra_includes, "openmp")
    if openmp.exists():
        return openmp, ""
    serial = library_path(name, sources, extra_includes, "serial")
    if serial.exists():
        return serial, "single-threaded build (cached; delete it to retry OpenMP)"
    try:
        return compile_variant(name, sources, extra_includes, "openmp"), ""
    except BuildError as openmp_error:
        try:
            path = compile_variant(name, sources, extra_includes, "serial")
        except BuildError:
            raise openmp_error from None
        return path, f"single-threaded build: the OpenMP build failed: {openmp_error}"


__all__ = [
    "ABI_VERSION",
    "BuildError",
    "build",
    "build_key",
    "cache_root",
    "compile_variant",
    "compiler",
    "library_path",
    "platform_tag",
]
