"""Optimizer surgery: add, select or reset rows of per-Gaussian parameters and keep optimizer state
aligned.

Densification changes the number of Gaussians N. Every per-Gaussian parameter (first dimension N)
and every per-element tensor in its optimizer state (Adam's ``exp_avg``, ``exp_avg_sq``,
``max_exp_avg_sq``, SGD's ``momentum_buffer``: any state tensor with the parameter's shape) must
follow its Gaussian:

- selecting rows keeps each surviving row's moments,
- appended rows start with zero moments,
- scalar state such as Adam's ``step`` is left unchanged (3DGS behaviour: the bias correction of new
  rows then uses the parameter's global step, exactly as in the reference implementation).

Parameters keep their identity: the new values are assigned to ``param.data``, so the optimizer's
param groups (one tensor each or several) and any ``requires_grad`` freezes stay valid. Their
``.grad`` is cleared because it no longer matches the shape; as in 3DGS the next
``optimizer.step()`` skips them until a new backward.
"""

from __future__ import annotations

from collections.abc import Iterable

import torch
from torch import nn


def make_adam(groups: list[dict], lr: float = 0.0, eps: float = 1e-15) -> torch.optim.Adam:
    """Adam as every Gaussian method here uses it (3DGS ``eps=1e-15``), in torch's fused
    single-kernel form.

    ``fused=True`` runs the whole update in one kernel per device (3× faster than the default on the
    CPU for thousands of Gaussians); its state (``step``, ``exp_avg``, ``exp_avg_sq``) is the
    default Adam's, so the row surgery below and checkpoints work unchanged.
    """
    return torch.optim.Adam(groups, lr=lr, eps=eps, fused=True)


def _row_states(
    optimizer: torch.optim.Optimizer | None, param: nn.Parameter
) -> dict[str, torch.Tensor]:
    """The per-element state tensors (same shape as ``param``) of ``param`` in ``optimizer``."""
    if optimizer is None:
        return {}
    state = optimizer.state.get(param)
    if not state:
        return {}
    return {
        k: v for k, v in state.items() if isinstance(v, torch.Tensor) and v.shape == param.shape
    }


def select_rows(
    params: Iterable[nn.Parameter], optimizer: torch.optim.Optimizer | None, index: torch.Tensor
) -> None:
    """Keep rows ``index`` (bool mask (N,) or int64 indices, may repeat) of every parameter and its
    state."""
    for param in params:
        states = _row_states(optimizer, param)
        param.data = param.data[index]
        for key, value in states.items():
            optimizer.state[param][key] = value[index]
        param.grad = None


def append_rows(
    params: Iterable[nn.Parameter],
    optimizer: torch.optim.Optimizer | None,
    rows: Iterable[torch.Tensor],
) -> None:
    """Append ``rows[i]`` (M, ...) to the i-th parameter (N, ...); the new rows get zero optimizer
    moments."""
    for param, new in zip(params, rows, strict=True):
        new = new.detach().to(device=param.device, dtype=param.dtype)
        if new.shape[1:] != param.shape[1:]:
            raise ValueError(
                f"cannot append rows of shape {tuple(new.shape)} to a parameter of "
                f"{tuple(param.shape)}"
            )
        states = _row_states(optimizer, param)
        param.data = torch.cat([param.data, new], dim=0)
        for key, value in states.items():
            optimizer.state[param][key] = torch.cat(
                [value, torch.zeros_like(new, dtype=value.dtype)], dim=0
            )
        param.grad = None


def replace_values(
    param: nn.Parameter,
    optimizer: torch.optim.Optimizer | None,
    values: torch.Tensor,
    reset_state: bool = True,
) -> None:
    """Overwrite ``param`` with ``values`` (same shape); with ``reset_state`` its moments become
    zero (3DGS)."""
    if values.shape != param.shape:
        raise ValueError(
            f"replacement of shape {tuple(values.shape)} for a parameter of {tuple(param.shape)}"
        )
    states = _row_states(optimizer, param) if reset_state else {}
    param.data = values.detach().to(device=param.device, dtype=param.dtype).clone()
    for key, value in states.items():
        optimizer.state[param][key] = torch.zeros_like(value)
    param.grad = None


__all__ = ["append_rows", "replace_values", "select_rows"]
