"""The device shim: CUDA requests of unmodified authors' code served by the CPU.

`install()` (called by the stand-in ``sitecustomize`` of an official job with ``device=cpu``; never
by olatbench itself) makes, for the rest of the process:

- every torch function or tensor method called with a CUDA device (``device="cuda"``, ``"cuda:0"``,
  ``torch.device("cuda")``, or a positional device as in ``x.to("cuda")``) use the CPU instead,
  through a `torch.overrides.TorchFunctionMode` that stays entered;
- ``Tensor.cuda(...)`` return the tensor on the CPU and ``Module.cuda(...)`` return the module
  unchanged;
- ``torch.load(..., map_location="cuda")`` (RNG's ``train.py:46`` loads its stage-1 checkpoint so)
  load onto the CPU: a CUDA device given as ``map_location`` (str or torch.device) becomes the CPU;
- ``torch.cuda.Stream``, ``stream``, ``current_stream``, ``Event``, ``synchronize``,
  ``empty_cache``, ``set_device`` harmless on the CPU: streams are placeholders whose
  ``wait_stream`` does nothing and ``stream(s)`` is an empty context (CPU work is already ordered);
  an ``Event`` records the wall clock, so ``start.elapsed_time(end)`` is the milliseconds between
  the two ``record()`` calls, as the CUDA event reports them after a synchronize.

``torch.cuda.is_available()`` stays False (code that asks takes its CPU path).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from typing import Any

import torch
from torch.overrides import TorchFunctionMode

_installed: dict[str, Any] = {}


def to_cpu_device(value: Any) -> Any:
    """``value`` with a CUDA device (str or torch.device) replaced by ``"cpu"``; anything else
    unchanged."""
    if isinstance(value, torch.device) and value.type == "cuda":
        return torch.device("cpu")
    if isinstance(value, str) and (value == "cuda" or value.startswith("cuda:")):
        return "cpu"
    return value


class CpuForCuda(TorchFunctionMode):
    """Rewrites CUDA device arguments (keyword ``device`` and positional devices) to the CPU."""

    def __torch_function__(self, func, types, args=(), kwargs=None):
        kwargs = dict(kwargs or {})
        if "device" in kwargs:
            kwargs["device"] = to_cpu_device(kwargs["device"])
        args = tuple(to_cpu_device(arg) for arg in args)
        return func(*args, **kwargs)


class Stream:
    """A CUDA stream on the CPU: every operation is already in order, so waiting does nothing."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        pass

    def wait_stream(self, stream: Any) -> None:
        pass

    def wait_event(self, event: Any) -> None:
        pass

    def synchronize(self) -> None:
        pass

    def record_event(self, event: Event | None = None) -> Event:
        event = event or Event()
        event.record()
        return event


class Event:
    """A CUDA event on the CPU: ``record()`` notes the wall clock; ``elapsed_time`` is in
    milliseconds."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.time: float | None = None

    def record(self, stream: Any = None) -> None:
        self.time = time.perf_counter()

    def synchronize(self) -> None:
        pass

    def wait(self, stream: Any = None) -> None:
        pass

    def query(self) -> bool:
        return True

    def elapsed_time(self, end: Event) -> float:
        if self.time is None or end.time is None:
            raise RuntimeError("elapsed_time: both events must be recorded first")
        return 1000.0 * (end.time - self.time)


_CURRENT = Stream()


@contextlib.contextmanager
def stream(value: Any = None) -> Iterator[None]:
    """``with torch.cuda.stream(s):`` on the CPU: nothing to switch."""
    yield


# One function object per replaced name: torch._dynamo's trace rules refuse one object under two
# names.
def synchronize(device: Any = None) -> None:
    """CPU work is already synchronous."""


def empty_cache() -> None:
    """No CUDA cache to empty."""


def set_device(device: Any) -> None:
    """There is one device, the CPU."""


def current_stream(device: Any = None) -> Stream:
    return _CURRENT


def _tensor_cuda(self: torch.Tensor, *args: Any, **kwargs: Any) -> torch.Tensor:
    return self.to("cpu")


def _module_cuda(self: torch.nn.Module, *args: Any, **kwargs: Any) -> torch.nn.Module:
    return self


def _load(*args: Any, **kwargs: Any) -> Any:
    """``torch.load`` with a CUDA ``map_location`` (str or torch.device) replaced by the CPU."""
    if "map_location" in kwargs:
        kwargs["map_location"] = to_cpu_device(kwargs["map_location"])
    elif len(args) > 1:
        args = (args[0], to_cpu_device(args[1]), *args[2:])
    return _installed["load"](*args, **kwargs)


def install() -> None:
    """Install the shim for the rest of the process (module docstring); a second call does
    nothing."""
    if _installed:
        return
    cuda = torch.cuda
    replacements = {
        "Stream": Stream,
        "Event": Event,
        "stream": stream,
        "current_stream": current_stream,
        "synchronize": synchronize,
        "empty_cache": empty_cache,
        "set_device": set_device,
    }
    for name, value in replacements.items():
        _installed["cuda." + name] = getattr(cuda, name, None)
        setattr(cuda, name, value)
    _installed["Tensor.cuda"], _installed["Module.cuda"] = torch.Tensor.cuda, torch.nn.Module.cuda
    torch.Tensor.cuda = _tensor_cuda  # type: ignore[method-assign]
    torch.nn.Module.cuda = _module_cuda  # type: ignore[method-assign]
    _installed["load"] = torch.load
    torch.load = _load  # type: ignore[assignment]
    mode = CpuForCuda()
    mode.__enter__()
    _installed["mode"] = mode


def uninstall() -> None:
    """Undo `install` (for tests)."""
    if not _installed:
        return
    _installed.pop("mode").__exit__(None, None, None)
    torch.Tensor.cuda = _installed.pop("Tensor.cuda")  # type: ignore[method-assign]
    torch.nn.Module.cuda = _installed.pop("Module.cuda")  # type: ignore[method-assign]
    torch.load = _installed.pop("load")  # type: ignore[assignment]
    for key in list(_installed):
        setattr(torch.cuda, key.removeprefix("cuda."), _installed.pop(key))
