"""The same floating-point results on every x86_64 machine: torch's CPU kernels at one vector width.

torch chooses its vectorised ATen kernels when it is imported, by the CPU's widest instruction set
(``AVX512`` or ``AVX2`` on x86_64), and the two round differently: the same seed then trains to other
numbers on machines of different vector width (measured: a 150-step SSD-GS run on mini ``diffuse_shadow``
ended at loss 0.2841240167617798 with AVX512 and 0.2841130495071411 with AVX2; thread count 1 vs 2 and
olatbench's C++ kernels, built without ``-march=native`` and with ``-ffp-contract=off``, changed nothing).
`pin_cpu_capability` sets ``ATEN_CPU_CAPABILITY=avx2`` before torch is imported, unless the user chose a
value; the ``olatbench`` command calls it first, so its runs agree across x86_64 machines with AVX2 or
wider (``benchmarks/bench_cpu_capability.py`` measures the cost). Python code that imports torch itself
gets the machine's choice unless it sets the variable first. `cpu_numerics` says what is in effect.
"""

from __future__ import annotations

import os
import platform
import sys

CAPABILITY_ENV = "ATEN_CPU_CAPABILITY"
PORTABLE_CAPABILITY = "avx2"
#: CPU flags that decide which kernels torch and the compilers may use (read from /proc/cpuinfo on Linux).
RELEVANT_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512_bf16", "amx_tile", "asimd", "sve")


def pin_cpu_capability() -> str | None:
    """Set ``$ATEN_CPU_CAPABILITY`` to ``avx2`` on x86_64 when nothing chose it yet; return the value in effect.

    Does nothing (returns the current value) when the variable is already set, when torch is already
    imported (too late to change), or on other architectures (no common width to pin to).
    """
    current = os.environ.get(CAPABILITY_ENV)
    if current is not None or "torch" in sys.modules:
        return current
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return None
    os.environ[CAPABILITY_ENV] = PORTABLE_CAPABILITY
    return PORTABLE_CAPABILITY


CPUINFO = "/proc/cpuinfo"


def cpuinfo_text(path: str | os.PathLike = CPUINFO) -> str:
    """The text of Linux's ``/proc/cpuinfo`` (the one reader of it), or "" where it cannot be read."""
    try:
        with open(path, encoding="utf-8", errors="replace") as handle:
            return handle.read()
    except OSError:  # not Linux
        return ""


def cpu_flags(text: str | None = None) -> list[str]:
    """The `RELEVANT_FLAGS` of the first CPU in ``text`` (default: this machine's `cpuinfo_text`)."""
    for line in (cpuinfo_text() if text is None else text).splitlines():
        if line.startswith(("flags", "Features")):
            present = set(line.split(":", 1)[1].split())
            return [flag for flag in RELEVANT_FLAGS if flag in present]
    return []


def cpu_numerics() -> dict[str, object]:
    """What decides CPU rounding in this process: torch's kernel width and threads (None without torch), the
    pin, the CPU flags."""
    try:
        import torch
    except ImportError:
        capability, threads = None, None
    else:
        capability, threads = torch.backends.cpu.get_cpu_capability(), torch.get_num_threads()
    return {"torch_cpu_capability": capability, "torch_threads": threads,
            CAPABILITY_ENV: os.environ.get(CAPABILITY_ENV), "cpu_flags": cpu_flags()}
