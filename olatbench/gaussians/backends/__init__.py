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
_warned_fallback = False


def cpu_backend_status() -> tuple[bool, str]:
    """(ok, detail) of the C++ CPU backend: builds/loads it if needed; ``detail`` is the library path or the
    reason it is unavailable (for ``olatbench doctor``)."""
    try:
        build.load()
    except build.BuildError as error:
        return False, str(error)
    path, note = build.loaded_path()
    return True, f"{path} ({note})" if note else str(path)


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
    global _warned_fallback
    if device.type == "cuda":
        return "cuda" if gsplat_available() else "torch"
    if device.type != "cpu" or dtype not in (torch.float32, torch.float64):
        return "torch"
    ok, detail = cpu_backend_status()
    if ok:
        return "cpu"
    if not _warned_fallback:
        _warned_fallback = True
        warnings.warn(
            "olatbench: the C++ CPU rasterizer is unavailable, falling back to the much slower torch "
            f"rasterizer. Reason: {detail}\nInstall a C++ compiler with OpenMP (e.g. `apt install g++`) or point "
            f"OLATBENCH_CXX at one; set {ENV_VAR}=torch to silence this warning.",
            RuntimeWarning,
            stacklevel=3,
        )
    return "torch"


def reset_fallback_warning() -> None:
    """Allow the fallback warning to be shown again (for tests)."""
    global _warned_fallback
    _warned_fallback = False


__all__ = ["BACKENDS", "ENV_VAR", "cpu_backend_status", "reset_fallback_warning", "resolve_backend"]
