"""The one place where ``--device auto`` becomes a torch device name.

``auto`` means ``cuda`` when torch sees a CUDA device, else ``cpu``. Every verb and the runner call
`resolve_device` before a method, a model or a calibration sees the name, so no torch call ever gets
``"auto"`` (``torch.device("auto")`` raises). Torch is imported only to resolve ``auto``, so a dry run
that keeps ``auto`` (the device enters no job id) stays torch-free; its time estimates name ``auto`` from what a
calibration stored (`olatbench.bench.estimate`), and only ``--calibrate`` resolves it.
"""

from __future__ import annotations

AUTO = "auto"


def resolve_device(name: str) -> str:
    """``"auto"`` -> ``"cuda"`` or ``"cpu"`` (whichever torch can use here); any other name unchanged."""
    if name != AUTO:
        return name
    import torch

    return "cuda" if torch.cuda.is_available() else "cpu"
