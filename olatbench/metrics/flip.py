"""NVIDIA ꟻLIP (Andersson et al. 2020/2021) through the optional ``flip-evaluator`` package.

HDR-ꟻLIP on linear-light images with a **fixed** exposure range, so that values are comparable across images
and methods (ꟻLIP's default derives the range from each reference image). Not part of the named protocols;
install with ``pip install flip-evaluator``.
"""

from __future__ import annotations

import importlib.util

import numpy as np

# Fixed HDR exposure bracket: one exposure per stop from -3 to +3 EV, ACES tone mapper, 67 pixels per degree.
HDR_PARAMETERS = {"startExposure": -3.0, "stopExposure": 3.0, "numExposures": 7, "tonemapper": "ACES", "ppd": 67.0}


def flip_available() -> bool:
    """True when ``flip-evaluator`` is installed."""
    return importlib.util.find_spec("flip_evaluator") is not None


def _checked(image: np.ndarray, name: str) -> np.ndarray:
    array = np.asarray(image, dtype=np.float32)
    if array.ndim != 3 or array.shape[-1] != 3:
        raise ValueError(f"{name}: expected an (H, W, 3) image, found shape {array.shape}")
    if not np.isfinite(array).all() or (array < 0).any():
        raise ValueError(f"{name}: HDR-FLIP needs finite, non-negative linear values")
    return np.ascontiguousarray(array)


def hdr_flip(pred: np.ndarray, gt: np.ndarray) -> float:
    """Mean HDR-ꟻLIP error of linear-light (H, W, 3) images (0 = identical) with `HDR_PARAMETERS`."""
    if not flip_available():
        raise RuntimeError("HDR-FLIP needs the optional package flip-evaluator: pip install flip-evaluator")
    import flip_evaluator

    _, mean, _ = flip_evaluator.evaluate(_checked(gt, "gt"), _checked(pred, "pred"), "HDR", inputsRGB=False,
                                         applyMagma=False, computeMeanError=True, parameters=dict(HDR_PARAMETERS))
    return float(mean)
