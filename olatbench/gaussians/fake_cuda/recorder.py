"""A dispatch mode that finds host syncs and device mixes among fake CUDA tensors, and goes on past
each.

Pushed above a ``FakeTensorMode``, `Recorder` sees every aten op first and classifies:

- **scalar reads** (``aten._local_scalar_dense``: ``.item()``, ``float(t)``, ``int(t)``,
  ``bool(t)``, ``.tolist()``) and ``aten.equal`` of a CUDA tensor: a sync; the value is substituted
  (`SUBSTITUTE`);
- **copies between host and device** (``_to_copy`` / ``copy_`` across CPU and CUDA: ``.cpu()``,
  ``.to("cuda")``, ``torch.tensor(..., device="cuda")``): a sync each way (a blocking copy waits for
  the device's stream), except an upload with ``non_blocking=True``, which the host queues without
  waiting;
- **data-dependent output sizes** on CUDA tensors (``nonzero``, boolean-mask indexing,
  ``repeat_interleave`` without ``output_size``, ``bincount``, ``unique``, ``masked_select``): a
  sync; the op runs as if the first half (rounded down) of every mask were true, so that a loop
  shrinking a set by masks ends, and repeats and counts sum to `SUBSTITUTE`'s count;
- **device mixes** (``FakeTensorDeviceMismatchError``: a CPU tensor of one or more dimensions in an
  op on CUDA tensors): a finding; the op then runs with the CPU tensors moved to CUDA.

Each finding keeps the frames of olatbench and its caller of the Python stack (innermost: where) and
the allowance block it ran in (`olatbench.gaussians.host_sync`). Substituted values are not the real
ones, so control flow after one may differ from a real run; shapes, dtypes and devices stay
consistent.
"""

from __future__ import annotations

import sysconfig
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from torch._subclasses.fake_tensor import (
    DataDependentOutputException,
    DynamicOutputShapeException,
    FakeTensorDeviceMismatchError,
)
from torch.utils._python_dispatch import TorchDispatchMode
from torch.utils._pytree import tree_flatten, tree_map

from olatbench.gaussians.host_sync import current_use

aten = torch.ops.aten
PACKAGE = Path(__file__).resolve().parents[2]  # .../olatbench
OWN = Path(__file__).resolve().parent  # frames of the dry run itself are not "where"
TORCH = Path(torch.__file__).resolve().parent
STDLIB = Path(sysconfig.get_paths()["stdlib"]).resolve()

#: More syncs than this in one phase stop it (a loop over device values that substituted values do
#: not end).
MAX_SYNCS_PER_PHASE = 2000
#: Values a dry run gives for data it cannot know: CUDA counts, CPU integers (indices stay valid),
#: floats, bools.
SUBSTITUTE = {"cuda_int": 64, "cpu_int": 0, "float": 1.0, "bool": True}


@dataclass(frozen=True)
class Finding:
    """``kind``: "sync" or "device mix"; ``what`` happened (the op and its meaning); ``where``: the
    innermost frame of olatbench or its caller ("olatbench/x.py:12 in f"); ``stack``: those frames,
    outermost first; ``phase``: what the dry run was doing; ``allowance``: the `host_sync` allowance
    it counts against (None: none)."""

    kind: str
    what: str
    where: str
    stack: tuple[str, ...]
    phase: str
    allowance: str | None = None
    over_limit: bool = False

    def line(self) -> str:
        allowed = (
            f" [allowed: {self.allowance}{', OVER ITS LIMIT' if self.over_limit else ''}]"
            if self.allowance
            else ""
        )
        return f"{self.phase}: {self.kind}: {self.what} at {self.where}{allowed}"


def _frames() -> tuple[str, ...]:
    """The frames of the current stack that are code of olatbench or of its caller
    (outermost first): not torch's, the standard library's or this package's own; olatbench's as
    ``olatbench/...:line in function``."""
    frames = []
    for frame in traceback.extract_stack():
        path = Path(frame.filename).resolve()
        if path.is_relative_to(OWN) or path.is_relative_to(TORCH) or path.is_relative_to(STDLIB):
            continue
        shown = (
            path.relative_to(PACKAGE.parent).as_posix()
            if path.is_relative_to(PACKAGE)
            else frame.filename
        )
        frames.append(f"{shown}:{frame.lineno} in {frame.name}")
    return tuple(frames)


def _tensors(args: Any, kwargs: Any) -> list[torch.Tensor]:
    return [t for t in tree_flatten((args, kwargs))[0] if isinstance(t, torch.Tensor)]


def _on_cuda(args: Any, kwargs: Any) -> bool:
    return any(t.device.type == "cuda" for t in _tensors(args, kwargs))


READS = {
    aten._local_scalar_dense.default: (
        ".item() / float() / int() / bool() / .tolist(): a scalar read"
    )
}
SIZES = {
    aten.nonzero.default: "nonzero (torch.where(mask), mask.nonzero())",
    aten.index.Tensor: "boolean-mask indexing x[mask]",
    aten.repeat_interleave.Tensor: "repeat_interleave without output_size",
    aten.repeat_interleave.self_Tensor: "repeat_interleave without output_size",
    aten.bincount.default: "bincount",
    aten._unique2.default: "unique",
    aten.unique_consecutive.default: "unique_consecutive",
    aten.unique_dim.default: "unique",
    aten.masked_select.default: "masked_select",
}


class Recorder(TorchDispatchMode):
    """Records `Finding`s of the ops it sees (see the module docstring); ``phase`` names what runs
    now."""

    def __init__(self) -> None:
        super().__init__()
        self.findings: list[Finding] = []
        self.phase = ""
        self._quiet = False  # while the recorder runs its own substitutes

    # ------------------------------------------------------------------------------------------
    # findings
    def record(self, kind: str, what: str) -> None:
        frames = _frames()
        where = frames[-1] if frames else "(unknown)"
        use = current_use() if kind == "sync" else None
        over = False
        if use is not None:
            use.syncs += 1
            over = use.allowance.limit is not None and use.syncs > use.allowance.limit
        self.findings.append(
            Finding(
                kind, what, where, frames, self.phase, use.allowance.name if use else None, over
            )
        )
        if sum(f.phase == self.phase for f in self.findings) > MAX_SYNCS_PER_PHASE:
            raise RuntimeError(
                f"more than {MAX_SYNCS_PER_PHASE} findings in {self.phase!r}, the last at {where}: "
                "a loop over values the device computes, which substituted values do not end"
            )

    # ------------------------------------------------------------------------------------------
    # dispatch
    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        if self._quiet:
            return func(*args, **kwargs)
        if func in READS:
            return self._read(func, args[0])
        if func is aten.equal.default:
            if _on_cuda(args, kwargs):
                self.record("sync", "torch.equal: a scalar read")
            return SUBSTITUTE["bool"]
        self._transfer(func, args, kwargs)
        try:
            return func(*args, **kwargs)
        except DynamicOutputShapeException:
            if func not in SIZES:
                raise
            if _on_cuda(args, kwargs):
                self.record("sync", f"{SIZES[func]}: an output size the device computes")
            return self._quiet_call(self._sized, func, args, kwargs)
        except DataDependentOutputException:
            self.record("sync", f"{func}: a value the device computes")
            raise
        except FakeTensorDeviceMismatchError:
            devices = sorted({str(t.device) for t in _tensors(args, kwargs)})
            self.record("device mix", f"{func} on {', '.join(devices)}")
            return self._quiet_call(self._on_one_device, func, args, kwargs)

    def _quiet_call(self, method, *args):
        self._quiet = True
        try:
            return method(*args)
        finally:
            self._quiet = False

    def _read(self, func, tensor: torch.Tensor) -> Any:
        on_cuda = tensor.device.type == "cuda"
        if on_cuda:
            self.record("sync", READS[func])
        if tensor.dtype == torch.bool:
            return SUBSTITUTE["bool"]
        if tensor.dtype.is_floating_point or tensor.dtype.is_complex:
            return SUBSTITUTE["float"]
        return SUBSTITUTE["cuda_int" if on_cuda else "cpu_int"]

    def _transfer(self, func, args, kwargs) -> None:
        if func is aten._to_copy.default:
            source = args[0].device
            target = torch.device(kwargs["device"]) if kwargs.get("device") is not None else source
            non_blocking = kwargs.get("non_blocking", False)
        elif func is aten.copy_.default:
            source, target = args[1].device, args[0].device
            non_blocking = kwargs.get("non_blocking", args[2] if len(args) > 2 else False)
        else:
            return
        if source.type == target.type or (non_blocking and source.type == "cpu"):
            # a non-blocking upload is queued on the stream (cudaMemcpyAsync): the host does not
            # wait
            return
        if "cuda" in (source.type, target.type):
            way = (
                "device-to-host copy (.cpu(), .numpy())"
                if source.type == "cuda"
                else "host-to-device copy (.to(cuda), torch.tensor/as_tensor(..., device=cuda))"
            )
            self.record("sync", f"{way}: a blocking copy")

    @staticmethod
    def _sized(func, args, kwargs) -> Any:
        """The op as if half of every mask were true and every data-dependent count
        `SUBSTITUTE`'s."""
        count = SUBSTITUTE["cuda_int"]
        if func is aten.nonzero.default:
            x = args[0]
            return torch.zeros(x.numel() // 2, x.dim(), dtype=torch.int64, device=x.device)
        if func is aten.index.Tensor:
            x, indices = args[0], []
            for index in args[1]:
                if index is not None and index.dtype == torch.bool:
                    indices += [
                        torch.zeros(index.numel() // 2, dtype=torch.int64, device=index.device)
                    ] * index.dim()
                else:
                    indices.append(index)
            return func(x, indices)
        if func in (aten.repeat_interleave.Tensor, aten.repeat_interleave.self_Tensor):
            return func(*args, **{**kwargs, "output_size": count})
        if func is aten.bincount.default:
            minlength = kwargs.get("minlength", args[2] if len(args) > 2 else 0)
            weights = kwargs.get("weights", args[1] if len(args) > 1 else None)
            dtype = (
                torch.int64
                if weights is None
                else torch.promote_types(weights.dtype, torch.float64)
            )
            return torch.zeros(minlength or count, dtype=dtype, device=args[0].device)
        if func is aten.masked_select.default:
            shape = torch.broadcast_shapes(args[0].shape, args[1].shape)
            return args[0].new_zeros(torch.Size(shape).numel() // 2)
        x = args[0]  # unique: every element distinct
        flat = x.reshape(-1).clone()
        inverse = torch.zeros(x.shape, dtype=torch.int64, device=x.device)
        counts = torch.ones(flat.numel(), dtype=torch.int64, device=x.device)
        return flat, inverse, counts

    @staticmethod
    def _on_one_device(func, args, kwargs) -> Any:
        device = next(t.device for t in _tensors(args, kwargs) if t.device.type == "cuda")

        # a fresh fake tensor on the device (values are not tracked anyway)
        def moved(t: Any) -> Any:
            if not isinstance(t, torch.Tensor) or t.device == device:
                return t
            return torch.zeros(t.shape, dtype=t.dtype, device=device).requires_grad_(
                t.requires_grad
            )

        return func(*tree_map(moved, args), **tree_map(moved, kwargs))


__all__ = ["SUBSTITUTE", "Finding", "Recorder"]
