"""MSE -> PSNR for logs and health checks, without torch: ``10 log10(peak² / max(MSE, 1e-12))``.

The floor keeps a perfect match finite (120 dB at peak 1) where a log line or a warning needs a
number; scores under a metric protocol use `olatbench.metrics.psnr`, which gives +inf for identical
images.
"""

from __future__ import annotations

import math

#: The smallest MSE converted (an exact match reads as 120 dB at peak 1, not +inf).
MSE_FLOOR = 1e-12


def psnr_from_mse(mse: float, peak: float = 1.0) -> float:
    """PSNR in dB of a mean squared error ``mse`` of values in [0, ``peak``]."""
    return 10.0 * math.log10(peak**2 / max(float(mse), MSE_FLOOR))
