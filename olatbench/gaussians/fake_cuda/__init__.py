"""A fake-CUDA dry run of the GPU path on any machine: host syncs and device mixes, found without a
GPU.

``with fake_cuda() as recorder:`` runs its body under torch's ``FakeTensorMode`` (shapes, dtypes and
devices without values; ``device="cuda"`` works on a CPU-only torch through the no-op CUDA guard of
`guard`), with the camera pass on the backend it takes on a GPU (``rasterize_cuda``: gsplat's Python
wrapper, its two compiled kernels replaced by the shape-level stand-ins of `gsplat_kernels`) and
`recorder.Recorder` listing every host sync and device mix with the file and line of olatbench code
that made it. ``Tensor.numpy()`` of a fake tensor gives arbitrary distinct numbers (the copy to the
host it needs is recorded where ``.cpu()`` made it), ``nn.Module.to`` gives a module new parameter
objects (torch's in-place swap refuses fake ones), and the backward pass is not run: autograd's
engine asks for the accelerator's current stream of a CUDA gradient, which a CPU-only torch does not
have, so every leaf tensor the graph reaches (and every tensor of it that called ``retain_grad``)
gets a fake gradient of its shape instead (`_FakeBackward`); the optimiser step and density control
then run on those.

What it cannot show: any value (kernel correctness, numerics), gsplat's compiled kernels themselves,
speed and memory (docs/gpu.md).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import torch
from torch._subclasses.fake_tensor import FakeTensor, FakeTensorMode

from . import gsplat_kernels
from .guard import ensure_fake_cuda_guard
from .recorder import SUBSTITUTE, Finding, Recorder

NUMPY_DTYPES = {
    torch.float16: np.float16,
    torch.float32: np.float32,
    torch.float64: np.float64,
    torch.bool: np.bool_,
    torch.uint8: np.uint8,
    torch.int32: np.int32,
    torch.int64: np.int64,
}


@contextmanager
def _patched(owner: object, name: str, value: object) -> Iterator[None]:
    original = getattr(owner, name)
    setattr(owner, name, value)
    try:
        yield
    finally:
        setattr(owner, name, original)


def _apply_replacing(self: torch.nn.Module, fn, recurse: bool = True) -> torch.nn.Module:
    """``nn.Module._apply`` (``.to``, ``.float``) with new Parameter objects instead of torch's
    in-place swap, which refuses fake parameters (FakeTensorMode's memo holds weak references to
    them)."""
    if recurse:
        for module in self.children():
            module._apply(fn)
    for key, param in self._parameters.items():
        if param is not None:
            with torch.no_grad():
                applied = fn(param)
            self._parameters[key] = torch.nn.Parameter(applied, requires_grad=param.requires_grad)
    for key, buffer in self._buffers.items():
        if buffer is not None:
            self._buffers[key] = fn(buffer)
    return self


class _FakeBackward:
    """``Tensor.backward`` and ``torch.autograd.grad`` without autograd's engine, which needs an
    accelerator's current stream for CUDA tensors and a CPU-only torch has none: every leaf the
    graph reaches, and every tensor of the graph that asked for ``retain_grad``, gets a fake
    gradient of its shape (added to one it has)."""

    def __init__(self) -> None:
        self.retained: list[torch.Tensor] = []
        self.retain_grad = torch.Tensor.retain_grad

    def record_retain(self, tensor: torch.Tensor) -> None:
        self.retain_grad(tensor)
        self.retained.append(tensor)

    @staticmethod
    def reached(roots) -> tuple[list[torch.Tensor], set]:
        nodes, leaves, stack = set(), [], [t.grad_fn for t in roots if t.grad_fn is not None]
        while stack:
            node = stack.pop()
            if node is None or node in nodes:
                continue
            nodes.add(node)
            if hasattr(node, "variable"):
                leaves.append(node.variable)
            stack += [next_node for next_node, _ in node.next_functions]
        return leaves, nodes

    def backward(self, tensor: torch.Tensor, *args, **kwargs) -> None:
        leaves, nodes = self.reached([tensor])
        for target in leaves + [t for t in self.retained if t.grad_fn in nodes]:
            target.grad = torch.zeros_like(target) if target.grad is None else target.grad + 0

    def grad(self, outputs, inputs, *args, **kwargs) -> tuple[torch.Tensor, ...]:
        inputs = (inputs,) if isinstance(inputs, torch.Tensor) else tuple(inputs)
        return tuple(torch.zeros_like(t) for t in inputs)


def _fake_numpy(original):
    draws = itertools.count(1)

    def numpy(self: torch.Tensor, *args, **kwargs) -> np.ndarray:
        if not isinstance(self, FakeTensor):
            return original(self, *args, **kwargs)
        if self.device.type != "cpu":
            raise TypeError(
                f"can't convert {self.device} device type tensor to numpy (Tensor.numpy of a CUDA "
                "tensor)"
            )
        values = np.random.default_rng(next(draws)).uniform(1.0, 2.0, tuple(self.shape))
        return values.astype(NUMPY_DTYPES.get(self.dtype, np.float64))

    return numpy


@contextmanager
def fake_cuda() -> Iterator[Recorder]:
    """Fake CUDA tensors, gsplat's kernels as shapes, and a `Recorder` of syncs and device mixes
    (module doc). Raises ``olatbench._native.BuildError`` when the no-op CUDA guard cannot be built,
    ImportError without gsplat."""
    import gsplat  # noqa: F401  (the camera pass runs gsplat's Python)

    from olatbench.gaussians import backends
    from olatbench.gaussians.backends import cuda

    ensure_fake_cuda_guard()
    recorder = Recorder()
    fake_backward = _FakeBackward()
    available = (
        True,
        "gsplat's Python with shape-level stand-ins of its compiled kernels (fake-CUDA dry run)",
    )
    with (
        _patched(backends, "gsplat_available", lambda: True),
        _patched(cuda, "gsplat_status", lambda: available),
        _patched(backends, "gsplat_status", lambda: available),
        _patched(torch.Tensor, "numpy", _fake_numpy(torch.Tensor.numpy)),
        _patched(torch.nn.Module, "_apply", _apply_replacing),
        _patched(torch.Tensor, "retain_grad", lambda t: fake_backward.record_retain(t)),
        _patched(torch.Tensor, "backward", lambda t, *a, **k: fake_backward.backward(t, *a, **k)),
        _patched(torch.autograd, "grad", fake_backward.grad),
        gsplat_kernels.install(),
        FakeTensorMode(allow_non_fake_inputs=True),
        recorder,
    ):
        yield recorder


__all__ = ["SUBSTITUTE", "Finding", "Recorder", "fake_cuda"]
