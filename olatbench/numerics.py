"""What decides CPU rounding, what olatbench pins before torch is imported, and the CPUs its figures
were checked on.

torch chooses its vectorised ATen kernels when it is imported, by the CPU's widest instruction set
(``AVX512`` or ``AVX2`` on x86_64), and the two round differently: the same seed then trains to
other numbers on machines of different vector width (measured: a 150-step SSD-GS run on mini
``diffuse_shadow`` ended at loss 0.2841240167617798 with AVX512 and 0.2841130495071411 with AVX2).
`pin_numerics` sets `PINS` (``ATEN_CPU_CAPABILITY=avx2``) before torch is imported, unless the user
chose a value; the ``olatbench`` command calls it first (``benchmarks/bench_cpu_capability.py``
measures the cost). Python code that imports torch itself gets the machine's choice unless it sets
the variables first.

The pin does not make every x86_64 CPU round alike: MKL and oneDNN choose their kernels by the CPU
themselves, and reductions split among threads add in another order, so the same seed gives other
last digits on other CPUs (and thread counts). `cpu_numerics` records everything that decides it
(`ROUNDING_ENV`, the CPU's `cpu_id` and flags), ``results.json`` carries it, and `SEED_FIGURES`
lists the CPUs the README's seed-0 figures were measured on, with the figures each gave
(`seed_figure_run` finds this CPU's). ``benchmarks/numerics_trace.py`` names the first step, tensor
and operation where two machines or settings part (docs/runner.md, "Same seed, same numbers").
"""

from __future__ import annotations

import json
import os
import platform
import re
import sys
from pathlib import Path
from typing import Any

CAPABILITY_ENV = "ATEN_CPU_CAPABILITY"
PORTABLE_CAPABILITY = "avx2"
#: What `pin_numerics` sets on x86_64 where the environment does not: torch's ATen kernels at AVX2.
PINS = {CAPABILITY_ENV: PORTABLE_CAPABILITY}
#: CPU flags that decide which kernels torch, MKL, oneDNN and the compilers may use (read from
#: /proc/cpuinfo on Linux; MKL and oneDNN take other code paths on AVX-512 CPUs with VNNI, FP16 or
#: AMX).
RELEVANT_FLAGS = (
    "sse4_2",
    "avx",
    "avx2",
    "fma",
    "avx512f",
    "avx512_vnni",
    "avx512_bf16",
    "avx512_fp16",
    "amx_tile",
    "asimd",
    "sve",
)


def pin_numerics() -> dict[str, str | None]:
    """Set each of `PINS` that the environment does not set yet, on x86_64, before torch is
    imported; return ``{variable: value in effect}`` for every pin.

    Leaves alone a variable the user set (their choice wins), everything once torch is imported (too
    late to change: its libraries read them at load), and other architectures
    (no common width to pin to).
    """
    if "torch" not in sys.modules and platform.machine().lower() in ("x86_64", "amd64"):
        for name, value in PINS.items():
            os.environ.setdefault(name, value)
    return {name: os.environ.get(name) for name in PINS}


CPUINFO = "/proc/cpuinfo"


def cpuinfo_text(path: str | os.PathLike = CPUINFO) -> str:
    """The text of Linux's ``/proc/cpuinfo`` (the one reader of it), or "" where it cannot be
    read."""
    try:
        with open(path, encoding="utf-8", errors="replace") as handle:
            return handle.read()
    except OSError:  # not Linux
        return ""


def cpu_flags(text: str | None = None) -> list[str]:
    """The `RELEVANT_FLAGS` of the first CPU in ``text`` (default: this machine's
    `cpuinfo_text`)."""
    for line in (cpuinfo_text() if text is None else text).splitlines():
        if line.startswith(("flags", "Features")):
            present = set(line.split(":", 1)[1].split())
            return [flag for flag in RELEVANT_FLAGS if flag in present]
    return []


#: ``/proc/cpuinfo`` keys naming the CPU's make (x86; ARM's are in `ARM_ID_KEYS`): what tells two
#: CPUs with the same flags apart (an AMD EPYC of family 25 and one of family 26 share every flag in
#: `RELEVANT_FLAGS`).
CPU_ID_KEYS = {
    "vendor": "vendor_id",
    "family": "cpu family",
    "model": "model",
    "stepping": "stepping",
}
ARM_ID_KEYS = {
    "vendor": "CPU implementer",
    "family": "CPU architecture",
    "model": "CPU part",
    "stepping": "CPU revision",
}


def cpu_id(text: str | None = None) -> dict[str, str | int | None]:
    """``{"vendor", "family", "model", "stepping"}`` of the first CPU in ``text`` (default: this
    machine's `cpuinfo_text`): e.g. ``{"vendor": "GenuineIntel", "family": 6, "model": 207,
    "stepping": 2}``; decimal values as ints (ARM's hexadecimal part numbers stay strings), None for
    what the text does not say."""
    fields: dict[str, str] = {}
    for line in (cpuinfo_text() if text is None else text).splitlines():
        if not line.strip():
            if fields:
                break  # the first processor's block ends
            continue
        key, _, value = (part.strip() for part in line.partition(":"))
        fields.setdefault(key, value)
    keys = CPU_ID_KEYS if "vendor_id" in fields else ARM_ID_KEYS
    found = {name: fields.get(key) or None for name, key in keys.items()}
    return {
        name: int(value) if value is not None and value.isdecimal() else value
        for name, value in found.items()
    }


def cpu_label(identity: dict[str, str | int | None]) -> str:
    """A CPU's id (`cpu_id`) as one line, e.g. ``GenuineIntel family 6 model 207 stepping 2`` (the
    fields known)."""
    parts = [str(identity.get("vendor") or "unknown vendor")]
    parts += [
        f"{key} {identity[key]}"
        for key in ("family", "model", "stepping")
        if identity.get(key) is not None
    ]
    return " ".join(parts)


#: Environment variables read at start-up that change which kernels run
#: (and so, maybe, the rounding): ATen's vector width, MKL's code path
#: (conditional numerical reproducibility) and instruction sets, oneDNN's instruction sets, the
#: thread counts of OpenMP and MKL (a sum split among threads adds in another order), and the copy
#: olatbench's C++ kernels run (``OLATBENCH_NATIVE_SIMD=baseline``: the 16-byte one instead of AVX2;
#: both give the same bits).
ROUNDING_ENV = (
    CAPABILITY_ENV,
    "MKL_CBWR",
    "MKL_ENABLE_INSTRUCTIONS",
    "ONEDNN_MAX_CPU_ISA",
    "DNNL_MAX_CPU_ISA",
    "OMP_NUM_THREADS",
    "MKL_NUM_THREADS",
    "OLATBENCH_NATIVE_SIMD",
)


def torch_libraries() -> dict[str, str | None]:
    """The MKL and oneDNN versions torch was built with (from ``torch.__config__.show()``; None
    where it does not name one or torch is missing): they choose their kernels by the CPU, apart
    from ATen's capability."""
    try:
        import torch
    except ImportError:
        return {"mkl": None, "onednn": None}
    shown = torch.__config__.show()
    mkl = re.search(r"Math Kernel Library Version (\d[\d.]*)", shown)
    onednn = re.search(r"(?:MKL-DNN|oneDNN) v(\S+)", shown)
    return {"mkl": mkl.group(1) if mkl else None, "onednn": onednn.group(1) if onednn else None}


def cpu_numerics() -> dict[str, object]:
    """What decides CPU rounding in this process: torch's kernel width and threads
    (None without torch), its MKL and oneDNN versions, every `ROUNDING_ENV` variable
    (None where unset), the CPU's id (`cpu_id`) and flags."""
    try:
        import torch
    except ImportError:
        capability, threads = None, None
    else:
        capability, threads = torch.backends.cpu.get_cpu_capability(), torch.get_num_threads()
    return {
        "torch_cpu_capability": capability,
        "torch_threads": threads,
        "torch_libraries": torch_libraries(),
        **{name: os.environ.get(name) for name in ROUNDING_ENV},
        "cpu_id": cpu_id(),
        "cpu_flags": cpu_flags(),
    }


SEED_FIGURES = Path(__file__).with_name("seed_figures.json")


def seed_figure_runs(path: str | os.PathLike = SEED_FIGURES) -> list[dict[str, Any]]:
    """The README's seed-0 runs, one per CPU measured (``seed_figures.json``: the one list of them;
    README.md and docs/runner.md quote it): ``cpu`` (`cpu_id`, None where not recorded), ``name``,
    ``flags``, ``threads``, ``pins``, ``date``, ``commit``, ``source`` and the test ``psnr`` /
    ``ssim`` per scene."""
    return json.loads(Path(path).read_text(encoding="utf-8"))["runs"]


def seed_figure_run(
    numerics: dict[str, Any], runs: list[dict[str, Any]] | None = None
) -> tuple[dict[str, Any] | None, list[str]]:
    """The run of `seed_figure_runs` made on this CPU (``numerics``: `cpu_numerics`): same vendor
    and family, and model and stepping where the run recorded them; and what differs from it here,
    each as a line: a variable of `ROUNDING_ENV` (those not in the run's ``pins`` were unset there;
    ``OMP_NUM_THREADS`` counts through the threads), torch's thread count where the run recorded it,
    a CPU flag it had. ``(None, [])`` for a CPU none was measured on."""
    identity = numerics["cpu_id"]
    for run in seed_figure_runs() if runs is None else runs:
        if all(value is None or identity.get(key) == value for key, value in run["cpu"].items()):
            settings = {
                name: run["pins"].get(name) for name in ROUNDING_ENV if name != "OMP_NUM_THREADS"
            }
            differences = [
                f"{name}: {numerics.get(name)} here, {value} there"
                for name, value in settings.items()
                if numerics.get(name) != value
            ]
            if run["threads"] is not None and numerics["torch_threads"] != run["threads"]:
                differences.append(
                    f"torch threads: {numerics['torch_threads']} here, {run['threads']} there"
                )
            missing = [flag for flag in run["flags"] if flag not in numerics["cpu_flags"]]
            if missing:
                differences.append(f"CPU flags {', '.join(missing)}: missing here")
            return run, differences
    return None, []
