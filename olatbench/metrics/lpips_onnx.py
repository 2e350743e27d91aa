"""LPIPS through onnxruntime: the torch `LPIPSNet` exported once to ONNX (cached on disk), run on
the CPU.

Export uses torch's TorchScript-based exporter (``dynamo=False``), which needs the ``onnx`` package;
a model already exported (``$XDG_CACHE_HOME/olatbench/weights/onnx/lpips_<net>-<sha12>.onnx``, keyed
by the sha256 of the weights and the opset) runs with onnxruntime alone. Values agree with the torch
path to ~1e-7.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import io
import warnings
from pathlib import Path

import numpy as np
import torch

from olatbench.atomic import write_bytes
from olatbench.metrics.lpips_net import LPIPSNet
from olatbench.metrics.lpips_networks import get_network
from olatbench.metrics.weights import cache_dir

OPSET = 17


def onnxruntime_installed() -> bool:
    """True when onnxruntime can be imported (checked without importing it)."""
    return importlib.util.find_spec("onnxruntime") is not None


def exporter_available() -> bool:
    """True when torch can export ONNX here (the ``onnx`` package is installed)."""
    return importlib.util.find_spec("onnx") is not None


def weights_digest(model: LPIPSNet) -> str:
    """sha256 of the model's tensors (names, shapes, bytes), to key the exported file."""
    digest = hashlib.sha256(f"{model.net}/opset{OPSET}".encode())
    for name, tensor in sorted(model.state_dict().items()):
        digest.update(name.encode())
        digest.update(str(tuple(tensor.shape)).encode())
        digest.update(tensor.detach().cpu().contiguous().numpy().tobytes())
    return digest.hexdigest()


def onnx_path(model: LPIPSNet, folder: Path | None = None) -> Path:
    """Where the exported model for these weights lives."""
    return (folder or cache_dir() / "onnx") / f"lpips_{model.net}-{weights_digest(model)[:12]}.onnx"


def export_onnx(model: LPIPSNet, path: Path) -> Path:
    """Export ``model`` (inputs x, y: (B, 3, H, W) in [-1, 1]; output (B,)) with dynamic batch and
    size."""
    if not exporter_available():
        raise RuntimeError("exporting LPIPS to ONNX needs the 'onnx' package (pip install onnx)")
    example = torch.zeros(1, 3, 64, 64)
    dynamic = {0: "batch", 2: "height", 3: "width"}
    buffer = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(
            model.cpu().float(),
            (example, example),
            buffer,
            dynamo=False,
            opset_version=OPSET,
            input_names=["x", "y"],
            output_names=["distance"],
            dynamic_axes={"x": dynamic, "y": dynamic, "distance": {0: "batch"}},
        )
    return write_bytes(path, buffer.getvalue())


class OnnxLPIPS:
    """Callable like `LPIPSNet`: ``(x, y)`` (B, 3, H, W) in [-1, 1] -> (B,) tensor, computed by
    onnxruntime."""

    def __init__(
        self, model: LPIPSNet, path: Path | None = None, threads: int | None = None
    ) -> None:
        import onnxruntime

        self.net = model.net
        self.path = path or onnx_path(model)
        if not self.path.is_file():
            export_onnx(model, self.path)
        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = threads or torch.get_num_threads()
        self.session = onnxruntime.InferenceSession(
            str(self.path), options, providers=["CPUExecutionProvider"]
        )

    def __call__(self, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        feed = {
            "x": np.ascontiguousarray(x.detach().cpu().float().numpy()),
            "y": np.ascontiguousarray(y.detach().cpu().float().numpy()),
        }
        return torch.from_numpy(self.session.run(None, feed)[0].reshape(-1))


@functools.lru_cache(maxsize=4)
def get_onnx_network(net: str = "alex", path: str | None = None) -> OnnxLPIPS:
    """The onnxruntime LPIPS for ``net`` with real weights (export cached on disk and in memory)."""
    return OnnxLPIPS(get_network(net, path, "cpu"))


def onnx_usable(net: str = "alex", path: str | None = None) -> bool:
    """True when onnxruntime is installed and the model is exported or exportable."""
    if not onnxruntime_installed():
        return False
    if exporter_available():
        return True
    return onnx_path(get_network(net, path, "cpu")).is_file()
