"""A device move under ``no_grad`` never carries an autograd graph, also when the tensor is already
there.

NRHints (291800d) renders a test view in chunks and keeps each chunk's result with
``rets.append(rendering_res.to( 'cpu'))`` inside ``get_eval_dicts``, which runs under
``torch.no_grad`` (``pipelines/base_pipeline.py:93-120``). Its normals come from
``torch.autograd.grad(..., create_graph=True)`` (``fields/sdf_field.py:136-147``), so they carry the
SDF network's double-backward graph. On a GPU, ``.to('cpu')`` is a copy made under ``no_grad``: the
copy has no graph and each chunk's graph is freed with the chunk. On the CPU, ``Tensor.to`` returns
the tensor itself, graph included, so every chunk's graph stays alive until the view is done: about
3 GB per 512-ray chunk, 23 GB when the kernel's OOM killer stopped the first 80×80 test view of a
mini scene (6,400 rays, 13 chunks) on this machine.

`install()` (called by ``site_nrhints/sitecustomize.py`` of a nrhints-official job with
``device=cpu``; never by olatbench itself) wraps ``torch.Tensor.to``: when the call returns the
tensor itself (nothing to move or convert), grad mode is off and the tensor requires grad, it
returns ``tensor.detach()`` — what the device copy gives on a GPU, without the copy (the result
shares the storage; NRHints only reads it). Every other call is unchanged: with grad mode on, a
conversion or a real move, or a tensor without grad.
"""

from __future__ import annotations

from typing import Any

import torch

_installed: dict[str, Any] = {}


def detaching_to(tensor: torch.Tensor, *args: Any, **kwargs: Any) -> torch.Tensor:
    """``Tensor.to`` that returns ``tensor.detach()`` instead of ``tensor`` itself under ``no_grad``
    (see above)."""
    moved = _installed["to"](tensor, *args, **kwargs)
    if moved is tensor and tensor.requires_grad and not torch.is_grad_enabled():
        return tensor.detach()
    return moved


def install() -> None:
    """Wrap ``torch.Tensor.to`` for the rest of the process (idempotent)."""
    if "to" not in _installed:
        _installed["to"] = torch.Tensor.to
        torch.Tensor.to = detaching_to


def uninstall() -> None:
    """Restore ``torch.Tensor.to`` (for tests)."""
    if "to" in _installed:
        torch.Tensor.to = _installed.pop("to")


__all__ = ["detaching_to", "install", "uninstall"]
