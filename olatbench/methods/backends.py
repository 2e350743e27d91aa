"""Which implementation each stage of a Gaussian method's training step runs on a device
(doctor, run logs).

Stages and their backends: ``rasterizer`` ``cuda`` (gsplat), ``cpu`` (C++) or ``torch``;
``projection``, ``binning`` and ``light_pass`` ``cpu`` or ``torch`` (``resolve_kernel_backend``: the
C++ kernel exactly when the rasterizer resolves to ``cpu``); ``ssim`` ``cpu`` or ``torch``;
``shading`` (SSD-GS only) ``cpu`` or ``torch``. Each answer comes from the stage's own resolver, so
the environment overrides (``OLATBENCH_RASTERIZER``, ``OLATBENCH_SSIM``, ``OLATBENCH_SHADING``) and
a failed C++ build are reflected.
"""

from __future__ import annotations

import torch

from olatbench.gaussians.backends import resolve_backend, resolve_kernel_backend
from olatbench.metrics.ssim import WINDOW_SIZE, resolve_ssim_backend


def stage_backends(
    device: torch.device | str, dtype: torch.dtype = torch.float32
) -> dict[str, str]:
    """Backend of every stage the Gaussian methods share, for ``dtype`` tensors on ``device``."""
    device = torch.device(device)
    stages = {"rasterizer": resolve_backend("auto", device, dtype)}
    for kind in ("projection", "binning", "light_pass"):
        stages[kind] = resolve_kernel_backend("auto", device, dtype, kind=kind)
    probe = torch.zeros(1, 3, WINDOW_SIZE, WINDOW_SIZE, device=device, dtype=dtype)
    stages["ssim"] = resolve_ssim_backend(probe, probe)
    return stages


def format_backends(backends: dict[str, str]) -> str:
    """``rasterizer=cpu, projection=cpu, …`` (one log line)."""
    return ", ".join(f"{stage}={name}" for stage, name in backends.items())


__all__ = ["format_backends", "stage_backends"]
