"""Colour conversions, compositing and quantisation: the one implementation everything calls.

Conventions: arrays are float (H, W, C) with values nominally in [0, 1] (linear
HDR data may exceed 1). ``"linear"`` is scene-linear light, ``"srgb"`` the
piecewise sRGB transfer function (IEC 61966-2-1), ``"gamma22"`` a pure 2.2
power curve as used by GS³ and SSD-GS to display their EXR data.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

ColourSpace = Literal["linear", "srgb", "gamma22"]
AlphaMode = Literal["straight", "premultiplied"]
COLOUR_SPACES: tuple[str, ...] = ("linear", "srgb", "gamma22")


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """Decode sRGB-encoded values to linear light (piecewise curve; negative input clamps to 0)."""
    x = np.clip(np.asarray(x, dtype=np.float32), 0.0, None)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """Encode linear light to sRGB (piecewise curve; negative input clamps to 0, >1 is kept)."""
    x = np.clip(np.asarray(x, dtype=np.float32), 0.0, None)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055).astype(np.float32)


def gamma_encode(x: np.ndarray, gamma: float = 2.2) -> np.ndarray:
    """Linear light to a pure power-law encoding ``x ** (1 / gamma)`` (negative clamps to 0)."""
    return np.power(np.clip(np.asarray(x, dtype=np.float32), 0.0, None), np.float32(1.0 / gamma))


def gamma_decode(x: np.ndarray, gamma: float = 2.2) -> np.ndarray:
    """A pure power-law encoding back to linear light ``x ** gamma``."""
    return np.power(np.clip(np.asarray(x, dtype=np.float32), 0.0, None), gamma).astype(np.float32)


_TO_LINEAR = {"linear": lambda x: np.asarray(x, dtype=np.float32), "srgb": srgb_to_linear, "gamma22": gamma_decode}
_FROM_LINEAR = {"linear": lambda x: np.asarray(x, dtype=np.float32), "srgb": linear_to_srgb, "gamma22": gamma_encode}


def convert_colourspace(x: np.ndarray, source: ColourSpace, target: ColourSpace) -> np.ndarray:
    """Convert colour values between ``linear``, ``srgb`` and ``gamma22`` (through linear light)."""
    for space in (source, target):
        if space not in COLOUR_SPACES:
            raise ValueError(f"unknown colour space {space!r}; expected one of {COLOUR_SPACES}")
    if source == target:
        return np.asarray(x, dtype=np.float32)
    return _FROM_LINEAR[target](_TO_LINEAR[source](x))


def premultiply(rgb: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Straight colour (H, W, 3) × alpha (H, W) -> premultiplied colour."""
    return (np.asarray(rgb, dtype=np.float32) * np.asarray(alpha, dtype=np.float32)[..., None]).astype(np.float32)


def unpremultiply(rgb: np.ndarray, alpha: np.ndarray, eps: float = 1e-8) -> np.ndarray:
    """Premultiplied colour -> straight colour; pixels with alpha ≤ eps become 0."""
    a = np.asarray(alpha, dtype=np.float32)[..., None]
    return np.where(a > eps, np.asarray(rgb, dtype=np.float32) / np.maximum(a, eps), 0.0).astype(np.float32)


def composite(rgb: np.ndarray, alpha: np.ndarray, background: np.ndarray | float,
              mode: AlphaMode = "straight") -> np.ndarray:
    """Composite colour (H, W, 3) with alpha (H, W) over a background colour (3,) or image (H, W, 3).

    ``straight``: ``rgb·a + bg·(1−a)``; ``premultiplied``: ``rgb + bg·(1−a)``.
    All three must be in the same colour space: compositing is done where the data lives,
    as the official pipelines do (sRGB PNGs are composited in sRGB, EXRs in linear light).
    """
    if mode not in ("straight", "premultiplied"):
        raise ValueError(f"unknown alpha mode {mode!r}; expected 'straight' or 'premultiplied'")
    rgb = np.asarray(rgb, dtype=np.float32)
    a = np.asarray(alpha, dtype=np.float32)[..., None]
    bg = np.asarray(background, dtype=np.float32)
    if not np.any(bg):  # a black background adds nothing
        return rgb * a if mode == "straight" else rgb.copy()
    if bg.ndim == 0:
        bg = np.full(rgb.shape[-1], bg, dtype=np.float32)
    out = np.multiply(1.0 - a, bg, dtype=np.float32)  # the background's share, full size
    out += rgb * a if mode == "straight" else rgb
    return out


def quantize_8bit(x: np.ndarray, mode: Literal["round", "truncate"] = "round") -> np.ndarray:
    """Values in [0, 1] to uint8 after clipping: ``round`` (nearest) or ``truncate``.

    ``truncate`` reproduces the official scripts that do ``(x * 255).astype(uint8)``.
    """
    scaled = np.clip(np.asarray(x, dtype=np.float32), 0.0, 1.0) * 255.0
    if mode == "round":
        return np.rint(scaled).astype(np.uint8)
    if mode == "truncate":
        return scaled.astype(np.uint8)
    raise ValueError(f"unknown quantisation mode {mode!r}; expected 'round' or 'truncate'")


def dequantize_8bit(x: np.ndarray) -> np.ndarray:
    """uint8 -> float32 in [0, 1]."""
    return np.asarray(x, dtype=np.float32) / 255.0
