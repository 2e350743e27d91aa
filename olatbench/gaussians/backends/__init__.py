"""Rasterizer backends and their selection.

Every backend implements ``(means2d (N,2), conics (N,3), opacities (N,), features (N,C), bins: TileBins) ->
(colour without background (H,W,C), final transmittance (H,W))``:

- ``torch``: ``torch_ref.rasterize_torch``, the reference and test oracle (any device, autograd backward);
- ``cpu``: ``cpu.rasterize_cpu``, the C++/OpenMP kernel with a hand-written backward (built on first use);
- ``cuda``: ``cuda.rasterize_cuda``, gsplat's CUDA kernel.

``resolve_backend("auto", device)`` picks ``cuda`` (gsplat) for CUDA tensors when gsplat is importable, else
``torch``; on the CPU it picks ``cpu`` when the C++ build works, else ``torch`` with one warning saying why.
The environment variable ``OLATBENCH_RASTERIZER`` (``torch``, ``cpu``, ``cuda`` or ``auto``) overrides
``"auto"``; an explicitly requested backend is used as asked (or fails with a clear error).
"""

from __future__ import annotations

import os
import warnings

import torch

from . import build
from .cuda import gsplat_available

BACKENDS = ("torch", "cpu", "cuda")
ENV_VAR = "OLATBENCH_RASTERIZER"
_warned_fallbacks: set[str] = set()


def cpu_backend_status() -> tuple[bool, str]:
    """(ok, detail) of the C++ CPU backend: builds/loads it if needed; ``detail`` is the library path or the
    reason it is unavailable (for ``olatbench doctor``)."""
    try:
        build.load()
    except build.BuildError as error:
        return False, str(error)
    path, note = build.loaded_path()
    return True, f"{path} ({note})" if note else str(path)


def cpu_kernels_or_warn(kernel: str, fallback: str, hint: str = "") -> bool:
    """Whether the C++ library is available for ``kernel`` (e.g. "CPU rasterizer"); when it is not, one
    RuntimeWarning per ``kernel`` (and process) says that ``fallback`` is used instead and why, plus ``hint``."""
    ok, detail = cpu_backend_status()
    if not ok and kernel not in _warned_fallbacks:
        _warned_fallbacks.add(kernel)
        warnings.warn(
            f"olatbench: the C++ {kernel} is unavailable, falling back to {fallback}. Reason: {detail}\n"
            f"Install a C++ compiler with OpenMP (e.g. `apt install g++`) or point OLATBENCH_CXX at one{hint}.",
            RuntimeWarning,
            stacklevel=4,  # past this helper and the resolver that calls it: where the kernel was asked for
        )
    return ok


def resolve_backend(requested: str, device: torch.device | str, dtype: torch.dtype = torch.float32) -> str:
    """The concrete backend name for ``requested`` ("auto" or one of BACKENDS) and the tensors' device."""
    device = torch.device(device)
    name = requested
    if requested == "auto":
        name = os.environ.get(ENV_VAR, "").strip().lower() or "auto"
        source = f"environment variable {ENV_VAR}={name!r}"
    else:
        source = f"backend={requested!r}"
    if name != "auto" and name not in BACKENDS:
        raise ValueError(f"unknown rasterizer backend from {source}; choose one of {', '.join(BACKENDS)} or 'auto'")
    if name == "auto":
        return _auto_backend(device, dtype)
    if name == "cpu" and device.type != "cpu":
        raise ValueError(f"{source} needs CPU tensors, got {device}; use 'auto', 'torch' or 'cuda'")
    if name == "cuda":
        if device.type != "cuda":
            raise ValueError(f"{source} needs CUDA tensors, got {device}")
        if not gsplat_available():
            raise RuntimeError(f"{source} needs gsplat (`pip install gsplat`); use 'torch' instead")
    return name


def _auto_backend(device: torch.device, dtype: torch.dtype) -> str:
    if device.type == "cuda":
        return "cuda" if gsplat_available() else "torch"
    if device.type != "cpu" or dtype not in (torch.float32, torch.float64):
        return "torch"
    return "cpu" if cpu_kernels_or_warn("CPU rasterizer", "the much slower torch rasterizer",
                                        f"; set {ENV_VAR}=torch to silence this warning") else "torch"


def reset_fallback_warning() -> None:
    """Allow the fallback warnings to be shown again (for tests)."""
    _warned_fallbacks.clear()


__all__ = ["BACKENDS", "ENV_VAR", "cpu_backend_status", "cpu_kernels_or_warn", "reset_fallback_warning",
           "resolve_backend"]
