"""The no-op CUDA device guard that fake CUDA tensors need in a CPU-only build of torch
(``guard.cpp``).

Built on first use with the C++ compiler of olatbench's kernels (`olatbench._native.build.compiler`)
against the installed torch's headers and ``libc10``, cached in the kernels' cache folder under a
key of the source, the torch version and the compiler, and loaded into the process. Unlike the
kernels it depends on torch's C++ ABI, hence the torch version in its key.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
from pathlib import Path

import torch

from olatbench._native.build import (
    BuildError,
    build_lock,
    cache_root,
    compile_library,
    compiler,
    compiler_version,
)

SOURCE = Path(__file__).with_name("guard.cpp")
NAME = "olatbench_fake_cuda_guard"


def _torch_dirs() -> tuple[Path, Path]:
    root = Path(torch.__file__).parent
    return root / "include", root / "lib"


def library_path() -> Path:
    """Where the guard library of this source, torch and compiler is cached."""
    digest = hashlib.sha256()
    command = compiler()
    for part in (
        SOURCE.read_bytes(),
        torch.__version__.encode(),
        str(_torch_dirs()[0]).encode(),
        "\0".join(command).encode(),
        compiler_version(tuple(command)).encode(),
    ):
        digest.update(part + b"\0")
    return cache_root() / f"{NAME}-{digest.hexdigest()[:16]}" / f"{NAME}.so"


def _compile(target: Path) -> None:
    include, lib = _torch_dirs()
    compile_library(
        [
            "-O1",
            "-shared",
            "-fPIC",
            "-std=c++17",
            f"-I{include}",
            str(SOURCE),
            f"-L{lib}",
            "-lc10",
            f"-Wl,-rpath,{lib}",
        ],
        target,
    )


@functools.cache
def ensure_fake_cuda_guard() -> str:
    """Make fake CUDA tensors usable in this process; returns what was done. Raises BuildError.

    A CUDA build of torch needs nothing (FakeTensorMode installs torch's own no-op guard when no
    device is present); a CPU-only build gets ``guard.cpp``'s, built and loaded once per process."""
    if torch.backends.cuda.is_built():
        return "torch is built with CUDA: FakeTensorMode's own no-op guard serves"
    target = library_path()
    if not target.exists():
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            with build_lock(target):
                if not target.exists():
                    _compile(target)
        except OSError as error:
            raise BuildError(
                f"cannot write the build cache {target.parent}: {error}; point XDG_CACHE_HOME at a "
                "writable folder"
            ) from error
    library = ctypes.CDLL(str(target))
    registered = library.olatbench_register_fake_cuda_guard()
    return f"no-op CUDA guard {'registered' if registered else 'already present'} ({target})"


__all__ = ["ensure_fake_cuda_guard", "library_path"]
