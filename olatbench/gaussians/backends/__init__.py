"""Rasterizer backends and their selection (also followed by projection, binning and the light
pass).

Every backend implements ``(means2d (N,2), conics (N,3), opacities (N,), features (N,C), bins:
TileBins) -> (colour without background (H,W,C), final transmittance (H,W))``:

- ``torch``: ``torch_ref.rasterize_torch``, the reference and test oracle
  (any device, autograd backward);
- ``cpu``: ``cpu.rasterize_cpu``, the C++/OpenMP kernel with a hand-written backward
  (built on first use);
- ``cuda``: ``cuda.rasterize_cuda``, gsplat's CUDA kernel.

``resolve_backend("auto", device)`` picks ``cuda`` (gsplat) for CUDA tensors when gsplat's CUDA
extension loads and ``cpu`` for CPU float32/float64 tensors when the C++ library builds, else
``torch``; a missing gsplat or a failed build falls back to ``torch`` with one warning saying why
(``olatbench._native.choose_backend``). The environment variable ``OLATBENCH_RASTERIZER``
(``torch``, ``cpu``, ``cuda`` or ``auto``) overrides ``"auto"``; an explicitly requested backend is
used as asked (or fails with a clear error).

``resolve_kernel_backend`` chooses for the kernels that have a C++ and a torch version (projection,
binning, light pass): ``"auto"`` takes the C++ one exactly when the rasterizer's choice for these
tensors is ``cpu``, so ``OLATBENCH_RASTERIZER=torch`` switches the whole Gaussian core to torch.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

import torch

from olatbench._native import Unavailable, always, choose_backend

from .cpu import LIBRARY
from .cuda import gsplat_available, gsplat_status

BACKENDS = ("torch", "cpu", "cuda")
ENV_VAR = "OLATBENCH_RASTERIZER"
KernelBackend = Literal["torch", "cpu"]


def cpu_backend_status() -> tuple[bool, str]:
    """(ok, detail) of the Gaussian core's C++ library: builds/loads it if needed; ``detail`` is the
    library path or the reason it is unavailable (for ``olatbench doctor``)."""
    return LIBRARY.status()


def _cpu_check(dtype: torch.dtype) -> Unavailable | None:
    if dtype not in (torch.float32, torch.float64):
        return Unavailable(f"it supports float32 and float64, not {dtype}")
    return LIBRARY.unavailable()


def _cuda_check() -> Unavailable | None:
    if gsplat_available():
        return None
    return Unavailable(
        f"it needs gsplat with its CUDA extension: {gsplat_status()[1]}", missing=True
    )


def resolve_backend(
    requested: str, device: torch.device | str, dtype: torch.dtype = torch.float32
) -> str:
    """The concrete rasterizer backend for ``requested`` ("auto" or one of BACKENDS) and the
    tensors' device and dtype (see the module docstring)."""
    return choose_backend(requested, torch.device(device).type, {
        "cuda": _cuda_check,
        "cpu": lambda: _cpu_check(dtype),
        "torch": always,
    }, kind="rasterizer", env_var=ENV_VAR)  # fmt: skip


def resolve_kernel_backend(
    requested: str,
    device: torch.device | str,
    dtype: torch.dtype,
    kind: str,
    inputs_check: Callable[[], Unavailable | None] = always,
) -> KernelBackend:
    """``"cpu"`` or ``"torch"`` for a Gaussian-core kernel named ``kind`` ("projection", ...) that
    has both.

    ``inputs_check`` says why the C++ version cannot take these inputs (None when it can).
    ``"auto"`` takes it when that check passes and ``resolve_backend("auto", device, dtype)`` is
    ``"cpu"`` (whose warning covers a failed build); ``"cpu"`` requires the check to pass and the
    library to build."""
    device = torch.device(device)

    def cpu_check() -> Unavailable | None:
        problem = inputs_check()
        if problem is None and requested == "auto":
            rasterizer = resolve_backend("auto", device, dtype)
            return (
                None if rasterizer == "cpu" else Unavailable(f"the rasterizer uses {rasterizer!r}")
            )
        return problem or _cpu_check(dtype)

    return choose_backend(requested, device.type, {"cpu": cpu_check, "torch": always}, kind=kind)


__all__ = [
    "BACKENDS",
    "ENV_VAR",
    "KernelBackend",
    "cpu_backend_status",
    "resolve_backend",
    "resolve_kernel_backend",
]
