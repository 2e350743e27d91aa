"""Torch tensors as arguments of the native libraries' C functions: data pointers, the dtype suffix
that picks a function's float (``_f32``) or double (``_f64``) version, and the OpenMP thread
count."""

from __future__ import annotations

import ctypes

import torch

FLOAT_SUFFIXES = {torch.float32: "f32", torch.float64: "f64"}


def pointer(t: torch.Tensor | None) -> ctypes.c_void_p:
    """The address of ``t``'s data (a CPU tensor laid out as the C function expects), or NULL for
    None."""
    return ctypes.c_void_p(None) if t is None else ctypes.c_void_p(t.data_ptr())


def thread_count(threads: int | None) -> int:
    """``threads`` (at least 1), or torch's intra-op thread count when None."""
    return max(1, int(threads if threads is not None else torch.get_num_threads()))


def float_suffix(dtype: torch.dtype, kernels: str) -> str:
    """``"f32"`` / ``"f64"`` for float32 / float64; TypeError naming ``kernels`` for any other
    dtype."""
    if dtype not in FLOAT_SUFFIXES:
        raise TypeError(f"{kernels} support float32 and float64, not {dtype}")
    return FLOAT_SUFFIXES[dtype]


__all__ = ["FLOAT_SUFFIXES", "float_suffix", "pointer", "thread_count"]
