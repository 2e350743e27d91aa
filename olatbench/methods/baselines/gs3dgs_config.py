"""The 3DGS configuration (torch-free: `olatbench methods show 3dgs` and dry runs read it without
torch)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from olatbench.methods.gaussian_config import GaussianConfig
from olatbench.methods.ranges import AT_LEAST_ONE, RATE, Range

MAX_SH_DEGREE = 3  # the highest degree `olatbench.methods.baselines.sh` evaluates


@dataclass
class GS3DConfig(GaussianConfig):
    """3DGS settings: the shared Gaussian fields (3DGS's defaults) and SH colour.
    ``sh_increase_interval`` is a cadence and does not scale with ``iterations``."""

    label: ClassVar[str] = "3DGS"
    ranges: ClassVar[dict[str, Range]] = {
        "sh_degree": Range(0, MAX_SH_DEGREE),
        "sh_increase_interval": AT_LEAST_ONE,
        "feature_lr": RATE,
    }

    sh_degree: int = 3
    sh_increase_interval: int = 1_000
    feature_lr: float = 2.5e-3  # DC; the higher-order coefficients use feature_lr / 20
