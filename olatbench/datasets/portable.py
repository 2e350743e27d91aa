"""float64 arithmetic whose bits do not depend on the CPU, for data that must be identical on every
machine.

numpy picks part of its code at run time by CPU: its transcendental ufuncs (``np.sin``, ``np.cos``,
``np.arctan2``, ``np.arccos``...) run SIMD loops on AVX-512 machines (SVML, a few ulp from the C
library) and the C library elsewhere, and ``@``, ``np.dot`` and the 1-D ``np.linalg.norm`` call the
BLAS kernel of the CPU (with or without fused multiply-adds, summing in its own order). The ``mini``
reference renders differed between an AVX-512 and an AVX2 machine for these reasons
(docs/synthetic-data.md). The helpers below use Python's ``math`` (the C library, the same code on
every x86-64 machine with FMA) one element at a time, and plain elementwise products and sums in a
fixed order. They are slower than numpy's loops (≈ 0.1 µs per element), which does not matter for
the generator's arrays (≤ a few hundred thousand elements).
"""

from __future__ import annotations

import math

import numpy as np

_sin = np.vectorize(math.sin, otypes=[np.float64])
_cos = np.vectorize(math.cos, otypes=[np.float64])
_atan2 = np.vectorize(math.atan2, otypes=[np.float64])
_acos = np.vectorize(math.acos, otypes=[np.float64])


def sin(x: np.ndarray | float) -> np.ndarray:
    """Element-wise sine (radians), float64, through the C library."""
    return _sin(np.asarray(x, dtype=np.float64))


def cos(x: np.ndarray | float) -> np.ndarray:
    """Element-wise cosine (radians), float64, through the C library."""
    return _cos(np.asarray(x, dtype=np.float64))


def arctan2(y: np.ndarray | float, x: np.ndarray | float) -> np.ndarray:
    """Element-wise atan2(y, x) in (-π, π], float64, through the C library."""
    return _atan2(np.asarray(y, dtype=np.float64), np.asarray(x, dtype=np.float64))


def arccos(x: np.ndarray | float) -> np.ndarray:
    """Element-wise arccos in [0, π] of ``x`` in [-1, 1], float64, through the C library."""
    return _acos(np.asarray(x, dtype=np.float64))


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Inner product over the last axis (broadcasting the others), summed left to right without
    BLAS."""
    a, b = np.broadcast_arrays(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
    total = a[..., 0] * b[..., 0]
    for k in range(1, a.shape[-1]):
        total = total + a[..., k] * b[..., k]
    return total


def norm(x: np.ndarray, keepdims: bool = False) -> np.ndarray:
    """Euclidean length over the last axis, without BLAS (``np.linalg.norm`` of a 1-D array calls
    ``dot``)."""
    length = np.sqrt(dot(x, x))
    return length[..., None] if keepdims else length
