"""The one place where a ``--device`` name is checked, and where ``--device auto`` becomes a torch
device name.

``auto`` means ``cuda`` when torch sees a CUDA device, else ``cpu``. Every verb and the runner call
`resolve_device` before a method, a model or a calibration sees the name, so no torch call ever gets
``"auto"`` (``torch.device("auto")`` raises), nor a device this machine does not have: the verb
refuses it up front as a usage error instead of a job failing on it. `check_device` checks the
spelling alone without torch (``TYPE`` or ``TYPE:INDEX``), so a dry run that keeps ``auto`` (the
device enters no job id) stays torch-free; its time estimates name ``auto`` from what a calibration
stored (`olatbench.bench.estimate`), and only ``--calibrate`` resolves it.
"""

from __future__ import annotations

import re

AUTO = "auto"
DEVICE_TYPES = ("cpu", "cuda", "mps", "xpu")  # the torch device types a Gaussian method can run on
_SPELLING = re.compile(rf"({'|'.join(DEVICE_TYPES)})(:\d+)?")


class DeviceError(ValueError):
    """A device name that is misspelt or that this machine's torch cannot use; the message names
    it."""


def check_device(name: str) -> str:
    """``name`` when it is ``auto`` or spelt ``TYPE[:INDEX]`` with TYPE one of `DEVICE_TYPES`
    (no torch import); a `DeviceError` saying the accepted forms otherwise."""
    if name != AUTO and not _SPELLING.fullmatch(str(name)):
        raise DeviceError(
            f"unknown device {name!r}: expected auto, {', '.join(DEVICE_TYPES)}, or one of them "
            "with an index (cuda:1)"
        )
    return name


def resolve_device(name: str) -> str:
    """``"auto"`` -> ``"cuda"`` or ``"cpu"`` (whichever torch can use here); any other name checked
    (`check_device`) and tried once (an empty tensor made on it), so a device torch lacks
    (no CUDA build, no such index) is a `DeviceError` naming it, never a traceback later."""
    import torch

    if check_device(name) == AUTO:
        return "cuda" if torch.cuda.is_available() else "cpu"
    try:
        torch.empty(0, device=name)
    # torch raises AssertionError when built without CUDA
    except (RuntimeError, AssertionError) as error:
        reason = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        raise DeviceError(f"device {name!r} is not usable here ({reason})") from None
    return name
