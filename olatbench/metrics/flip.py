"""NVIDIA ꟻLIP (Andersson et al. 2020/2021) through the optional ``flip-evaluator`` package.

* `ldr_flip`: LDR-ꟻLIP of display-encoded (sRGB) images in [0, 1], at 67 pixels per degree; the
  ``flip`` metric of the protocols that list it (``olatbench-v1-flip``), None per image when the
  package is not installed.
* `hdr_flip`: HDR-ꟻLIP on linear-light images with a **fixed** exposure range, so that values are
  comparable across images and methods (ꟻLIP's default derives the range from each reference image).

Install with ``pip install flip-evaluator`` (the ``flip`` extra).
"""

from __future__ import annotations

import importlib.util
import warnings
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from olatbench.metrics.protocols import Protocol
    from olatbench.metrics.registry import MetricBatch

# Fixed HDR exposure bracket: one exposure per stop from -3 to +3 EV, ACES tone mapper, 67 pixels
# per degree.
HDR_PARAMETERS = {
    "startExposure": -3.0,
    "stopExposure": 3.0,
    "numExposures": 7,
    "tonemapper": "ACES",
    "ppd": 67.0,
}
# LDR-ꟻLIP's viewing condition, fixed: 67 pixels per degree (ꟻLIP's default: a 0.7 m distance to a
# 0.7 m wide 3840-pixel monitor).
LDR_PARAMETERS = {"ppd": 67.0}
INSTALL_HINT = "pip install flip-evaluator"
_WARNED: list[bool] = []


def flip_available() -> bool:
    """True when ``flip-evaluator`` is installed."""
    return importlib.util.find_spec("flip_evaluator") is not None


def _checked(image: np.ndarray, name: str, upper: float = np.inf) -> np.ndarray:
    array = np.asarray(image, dtype=np.float32)
    if array.ndim != 3 or array.shape[-1] != 3:
        raise ValueError(f"{name}: expected an (H, W, 3) image, found shape {array.shape}")
    if not np.isfinite(array).all() or (array < 0).any() or (array > upper).any():
        wanted = (
            "finite, non-negative linear values"
            if upper == np.inf
            else f"finite values in [0, {upper:g}]"
        )
        raise ValueError(f"{name}: {'HDR' if upper == np.inf else 'LDR'}-FLIP needs {wanted}")
    return np.ascontiguousarray(array)


def hdr_flip(pred: np.ndarray, gt: np.ndarray) -> float:
    """Mean HDR-ꟻLIP error of linear-light (H, W, 3) images (0 = identical) with
    `HDR_PARAMETERS`."""
    if not flip_available():
        raise RuntimeError(f"HDR-FLIP needs the optional package flip-evaluator: {INSTALL_HINT}")
    import flip_evaluator

    _, mean, _ = flip_evaluator.evaluate(
        _checked(gt, "gt"),
        _checked(pred, "pred"),
        "HDR",
        inputsRGB=False,
        applyMagma=False,
        computeMeanError=True,
        parameters=dict(HDR_PARAMETERS),
    )
    return float(mean)


def ldr_flip(pred: np.ndarray, gt: np.ndarray) -> float:
    """Mean LDR-ꟻLIP error of sRGB-encoded (H, W, 3) images in [0, 1] (0 = identical) with
    `LDR_PARAMETERS`."""
    if not flip_available():
        raise RuntimeError(f"LDR-FLIP needs the optional package flip-evaluator: {INSTALL_HINT}")
    import flip_evaluator

    _, mean, _ = flip_evaluator.evaluate(
        _checked(gt, "gt", 1.0),
        _checked(pred, "pred", 1.0),
        "LDR",
        inputsRGB=True,
        applyMagma=False,
        computeMeanError=True,
        parameters=dict(LDR_PARAMETERS),
    )
    return float(mean)


def protocol_flip(batch: MetricBatch, protocol: Protocol) -> list[float | None]:
    """The ``flip`` metric: `ldr_flip` per image of the protocol's (quantised) images; None per
    image, with a warning once, when flip-evaluator is not installed. Masked protocols cannot list
    it (ꟻLIP has no mask)."""
    if batch.mask is not None:
        raise ValueError(
            f"protocol {protocol.id}: FLIP has no masked form; list it in unmasked protocols only"
        )
    if not flip_available():
        if not _WARNED:
            _WARNED.append(True)
            warnings.warn(f"FLIP is reported as None: {INSTALL_HINT}", stacklevel=3)
        return [None] * len(batch)
    preds = batch.pred.permute(0, 2, 3, 1).detach().cpu().numpy()
    gts = batch.gt.permute(0, 2, 3, 1).detach().cpu().numpy()
    return [ldr_flip(pred, gt) for pred, gt in zip(preds, gts, strict=True)]
