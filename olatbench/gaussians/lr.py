"""Learning-rate schedules for Gaussian training (the 3DGS ``get_expon_lr_func``)."""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial


def exponential_lr(
    step: int,
    lr_init: float,
    lr_final: float,
    max_steps: int,
    delay_steps: int = 0,
    delay_mult: float = 1.0,
) -> float:
    """Log-linear decay from ``lr_init`` (step 0) to ``lr_final`` (step ``max_steps``, held after),
    3DGS-style.

    ``lr(step) = delay(step) · exp((1 - t) · log(lr_init) + t · log(lr_final))`` with ``t =
    clip(step / max_steps, 0, 1)``. With ``delay_steps > 0`` the rate is additionally scaled by
    ``delay(step) = delay_mult + (1 - delay_mult) · sin(π/2 · clip(step / delay_steps, 0, 1))`` (a
    smooth warm-up from ``delay_mult``); otherwise ``delay = 1``. Negative steps and ``lr_init ==
    lr_final == 0`` give 0 (the parameter is frozen).
    """
    if step < 0 or (lr_init == 0.0 and lr_final == 0.0):
        return 0.0
    if lr_init <= 0.0 or lr_final <= 0.0:
        raise ValueError(
            f"exponential_lr needs lr_init > 0 and lr_final > 0 (or both 0), got {lr_init}, "
            f"{lr_final}"
        )
    if max_steps <= 0:
        raise ValueError(f"exponential_lr needs max_steps > 0, got {max_steps}")
    if delay_steps > 0:
        ramp = min(max(step / delay_steps, 0.0), 1.0)
        delay = delay_mult + (1.0 - delay_mult) * math.sin(0.5 * math.pi * ramp)
    else:
        delay = 1.0
    t = min(max(step / max_steps, 0.0), 1.0)
    return delay * math.exp(math.log(lr_init) * (1.0 - t) + math.log(lr_final) * t)


def exponential_lr_schedule(
    lr_init: float, lr_final: float, max_steps: int, delay_steps: int = 0, delay_mult: float = 1.0
) -> Callable[[int], float]:
    """``step -> exponential_lr(step, ...)`` with the other arguments bound
    (the 3DGS closure form)."""
    return partial(
        exponential_lr,
        lr_init=lr_init,
        lr_final=lr_final,
        max_steps=max_steps,
        delay_steps=delay_steps,
        delay_mult=delay_mult,
    )


__all__ = ["exponential_lr", "exponential_lr_schedule"]
