"""Native (C++) kernels: compile, cache and load each owner's library; choose between a kernel's
backends.

A leaf: imports nothing of olatbench, so every layer may use it (``metrics`` builds its SSIM kernel
without the Gaussian core). The owners keep their C++ beside their Python and declare one
``NativeLibrary`` each:

- ``olatbench/gaussians/csrc/`` -> ``olatbench_gaussians`` (rasterizer, projection, binning, light
  pass), declared in ``gaussians/backends/cpu.py``;
- ``olatbench/metrics/csrc/ssim.cpp`` -> ``olatbench_ssim`` (the SSIM training loss), in
  ``metrics/ssim_cpu.py``;
- ``olatbench/methods/ssdgs/csrc/shading.cpp`` -> ``olatbench_ssdgs_shading``, in
  ``methods/ssdgs/shading_cpu.py``.

Modules: ``build`` (compiler, build key, cache, lock), ``library`` (``NativeLibrary``, typed symbol
tables), ``backends`` (``choose_backend``), ``tensors`` (torch tensors as C arguments; the one
module that imports torch, so import it by name). Headers shared by all libraries live in
``include/``.
"""

from .backends import Unavailable, always, choose_backend, reset_fallback_warnings
from .build import ABI_VERSION, BuildError
from .library import FLOAT_TYPES, Library, NativeLibrary, Signature, per_float

__all__ = [
    "ABI_VERSION",
    "FLOAT_TYPES",
    "BuildError",
    "Library",
    "NativeLibrary",
    "Signature",
    "Unavailable",
    "always",
    "choose_backend",
    "per_float",
    "reset_fallback_warnings",
]
