"""Reduced-precision per-Gaussian networks: the ``network_precision`` of SSD-GS and GS³.

``"fp32"`` (default) runs the networks as they always ran: no autocast, bit-identical to a build
without this module. ``"bf16"`` and ``"fp16"`` run the networks' bodies (their Linear layers and
activations) under ``torch.autocast`` at that dtype: the weights stay float32 parameters (autocast
casts them per call), the network input is the float32 encoding (cast at each Linear) and the output
is cast back to float32 before the output nonlinearity (sigmoid, dipole profile), so everything
outside the networks — encodings, shading, rasterization, loss, Adam — stays float32.

Where each precision is allowed (`precision_unsupported`):

* ``bf16``: CUDA devices with bf16 (``torch.cuda.is_bf16_supported``), and CPUs with a native bf16
  matrix instruction, AMX (``amx_tile``) or AVX512-BF16 (``avx512_bf16``), where oneDNN runs bf16
  matmuls faster than float32. Elsewhere torch emulates bf16 by conversion and it is slower than
  float32, so it is refused.
* ``fp16``: CUDA only, with dynamic loss scaling (`LossScaler`): float16's range is narrow enough
  for the networks' gradients to underflow. bf16 has float32's range and needs none.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import torch

from olatbench.methods.shading.config import NETWORK_PRECISIONS as PRECISIONS
from olatbench.numerics import cpu_flags

DTYPES = {"fp32": torch.float32, "bf16": torch.bfloat16, "fp16": torch.float16}
#: CPU flags (``/proc/cpuinfo``) of a native bf16 matrix instruction, the faster first.
BF16_CPU_FLAGS = ("amx_tile", "avx512_bf16")


def fast_bf16_cpu_flag(flags: Iterable[str] | None = None) -> str | None:
    """The CPU feature that makes bf16 matmuls fast here (``"amx_tile"`` or ``"avx512_bf16"``), or
    None.

    ``flags``: CPU flags to use instead of this machine's (`olatbench.numerics.cpu_flags`)."""
    present = set(cpu_flags() if flags is None else flags)
    return next((flag for flag in BF16_CPU_FLAGS if flag in present), None)


def precision_unsupported(precision: str, device: torch.device | str) -> str | None:
    """Why the networks cannot run at ``precision`` on ``device`` here (None: they can)."""
    if precision not in PRECISIONS:
        return f"unknown precision {precision!r}; choose one of {', '.join(PRECISIONS)}"
    device = torch.device(device)
    if precision == "fp32":
        return None
    if device.type == "cuda":
        if precision == "bf16" and not torch.cuda.is_bf16_supported():
            return f"this GPU ({torch.cuda.get_device_name(device)}) has no bf16 support"
        return None
    if precision == "fp16":
        return (
            f"fp16 runs on CUDA only (device {device.type!r}); on a CPU with AMX or AVX512-BF16 "
            "use bf16"
        )
    if device.type != "cpu":
        return f"bf16 networks run on CUDA and on CPUs only, not on {device.type!r}"
    if fast_bf16_cpu_flag() is None:
        return (
            "this CPU has neither AMX (amx_tile) nor AVX512-BF16 (avx512_bf16), so bf16 matmuls "
            "are emulated and slower than float32"
        )
    return None


def check_precision(precision: str, device: torch.device | str, label: str) -> None:
    """Raise one `ValueError` naming ``label``'s ``network_precision`` when
    `precision_unsupported`."""
    reason = precision_unsupported(precision, device)
    if reason is not None:
        raise ValueError(
            f"{label}: network_precision={precision!r} is not supported here: {reason}. "
            "Use network_precision=fp32 (the default)."
        )


def run_network(
    network: Callable[[torch.Tensor], torch.Tensor], x: torch.Tensor, precision: str
) -> torch.Tensor:
    """``network(x)`` at ``precision``: as is for ``"fp32"``; otherwise under ``torch.autocast`` at
    that dtype on ``x``'s device, the output cast back to float32."""
    if precision == "fp32":
        return network(x)
    with torch.autocast(x.device.type, dtype=DTYPES[precision]):
        out = network(x)
    return out.float()


class LossScaler:
    """Dynamic loss scaling for fp16 networks (the scheme of ``torch.amp.GradScaler``, applied to
    every gradient a training step uses, including the retained 2D-mean gradient that density
    control reads, and skipping the whole step — every optimiser and the densification statistics —
    when any gradient overflowed).

    ``scale`` starts at ``initial``, halves after a step with a non-finite gradient and doubles
    after ``growth_interval`` finite steps in a row."""

    def __init__(self, initial: float = 2.0**16, growth_interval: int = 2000) -> None:
        self.scale = float(initial)
        self.growth_interval = int(growth_interval)
        self.finite_steps = 0

    def scaled(self, loss: torch.Tensor) -> torch.Tensor:
        return loss * self.scale

    @torch.no_grad()
    def unscale(self, gradients: Iterable[torch.Tensor | None]) -> bool:
        """Divide the ``gradients`` by the scale in place; True when all of them are finite."""
        finite = True
        for grad in gradients:
            if grad is not None:
                grad.mul_(1.0 / self.scale)
                finite = finite and bool(torch.isfinite(grad).all())
        return finite

    def update(self, finite: bool) -> None:
        """Adjust the scale after a step (``finite``: whether its gradients were)."""
        if not finite:
            self.scale /= 2.0
            self.finite_steps = 0
            return
        self.finite_steps += 1
        if self.finite_steps >= self.growth_interval:
            self.scale *= 2.0
            self.finite_steps = 0

    def state_dict(self) -> dict[str, float]:
        return {"scale": self.scale, "finite_steps": self.finite_steps}

    def load_state_dict(self, state: dict[str, float]) -> None:
        self.scale, self.finite_steps = float(state["scale"]), int(state["finite_steps"])


def loss_scaler_for(precision: str) -> LossScaler | None:
    """The loss scaler a training step at ``precision`` needs (fp16), or None."""
    return LossScaler() if precision == "fp16" else None


__all__ = [
    "BF16_CPU_FLAGS",
    "DTYPES",
    "PRECISIONS",
    "LossScaler",
    "check_precision",
    "fast_bf16_cpu_flag",
    "loss_scaler_for",
    "precision_unsupported",
    "run_network",
]
