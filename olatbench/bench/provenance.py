"""What a results.json records about where and when it was made: timestamps, hardware, library
versions.

One implementation for ``olatbench run`` (`olatbench.bench.execute`) and ``olatbench evaluate``
(`olatbench.bench.evaluate`), so both files carry the same keys with the same meaning.

* Timestamps are UTC, ISO 8601 with seconds (``2026-11-24T07:36:34+00:00``).
* Hardware: the CPU model (Linux ``/proc/cpuinfo`` "model name", else ``platform.processor()``),
  physical cores (distinct (physical id, core id) pairs of ``/proc/cpuinfo``; ``null`` where that
  file does not say), logical threads (``os.cpu_count()``), threads this process may use
  (its CPU affinity), and every CUDA device torch sees, with its name and total memory in MiB (an
  empty list without CUDA or without torch), and what decides CPU rounding
  (`olatbench.numerics.cpu_numerics`: torch's ATen kernel width, its thread count,
  ``ATEN_CPU_CAPABILITY``, the relevant CPU flags).
"""

from __future__ import annotations

import os
import platform
import sys
from datetime import datetime, timezone
from typing import Any

import numpy as np

from olatbench import __version__
from olatbench.numerics import CPUINFO, cpu_numerics, cpuinfo_text


def utc_now() -> str:
    """The current time as UTC ISO 8601 with seconds."""
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _cpuinfo(text: str) -> tuple[str | None, int | None]:
    """(model name, physical cores) from the text of ``/proc/cpuinfo``; None for what it does not
    say."""
    model, cores, physical = None, set(), "0"
    for line in text.splitlines():
        key, _, value = (part.strip() for part in line.partition(":"))
        if key == "model name" and model is None:
            model = value or None
        elif key == "physical id":
            physical = value
        elif key == "core id":
            cores.add((physical, value))
    return model, len(cores) or None


def cpu_identity(cpuinfo: str | os.PathLike = CPUINFO) -> dict[str, Any]:
    """``{"model", "cores", "threads", "usable_threads"}`` of this machine
    (see the module docstring)."""
    model, cores = _cpuinfo(cpuinfo_text(cpuinfo))
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {
        "model": model or platform.processor() or None,
        "cores": cores,
        "threads": os.cpu_count(),
        "usable_threads": usable,
    }


def gpu_identity() -> list[dict[str, Any]]:
    """``[{"index", "name", "memory_mb"}]`` for every CUDA device torch sees
    (empty without torch or CUDA)."""
    try:
        import torch
    except ImportError:
        return []
    if not torch.cuda.is_available():
        return []
    devices = []
    for index in range(torch.cuda.device_count()):
        properties = torch.cuda.get_device_properties(index)
        devices.append(
            {
                "index": index,
                "name": properties.name,
                "memory_mb": round(properties.total_memory / 2**20, 1),
            }
        )
    return devices


def hardware_identity() -> dict[str, Any]:
    """``{"machine", "cpu": cpu_identity(), "gpus": gpu_identity(), "numerics": cpu_numerics()}``
    (numerics: torch's CPU kernel width and threads, ``$ATEN_CPU_CAPABILITY`` and the CPU flags that
    change rounding)."""
    return {
        "machine": platform.machine(),
        "cpu": cpu_identity(),
        "gpus": gpu_identity(),
        "numerics": cpu_numerics(),
    }


def library_versions() -> dict[str, str | None]:
    """Versions of the libraries that can change a result (``null`` for one that is not
    installed)."""
    versions: dict[str, str | None] = {
        "olatbench": __version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
    }
    try:
        import torch

        versions["torch"], versions["cuda"] = torch.__version__, torch.version.cuda
    except ImportError:
        versions["torch"] = versions["cuda"] = None
    for name, module in (("opencv", "cv2"), ("openimageio", "OpenImageIO")):
        try:
            versions[name] = __import__(module).__version__
        except Exception:
            versions[name] = None
    versions["platform"] = platform.platform()
    return versions


def peak_rss_mb() -> float:
    """Peak resident memory of this process in MiB (``ru_maxrss`` is KiB on Linux, bytes on
    macOS)."""
    import resource

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (2**20 if sys.platform == "darwin" else 2**10)
