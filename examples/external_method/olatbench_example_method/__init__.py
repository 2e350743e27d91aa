"""A minimal external method: predicts the mean training image whatever the light
(a constant baseline).

Install it with ``pip install -e examples/external_method`` and run ``olatbench run --method
mean-image ...``. It learns nothing (``training_iterations = 0``): `setup` computes the mean, the
runner takes no training step whatever the suite's iteration count, and the one checkpoint (step 0)
holds the mean for ``olatbench view``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import torch

from olatbench.methods import Method, Views


@dataclass
class MeanImageConfig:
    iterations: int = 0  # learning-free: no training step


class MeanImage(Method):
    """``rgb`` = the per-pixel mean of the training images (H, W, 3), in the training colour
    space."""

    name: ClassVar[str] = "mean-image"
    config_class: ClassVar[type] = MeanImageConfig
    presets: ClassVar[dict[str, dict[str, Any]]] = {}
    description: ClassVar[str] = (
        "Example external method: the mean training image, blind to the light."
    )
    training_iterations: ClassVar[int | None] = 0  # learning-free, whatever the suite says

    def setup(self, train: Views, device, seed: int) -> None:
        self.mean = torch.from_numpy(train.images).to(device).mean(dim=0)  # (H, W, 3)

    def train_step(self, step: int) -> dict[str, float]:
        raise RuntimeError("mean-image takes no training step (training_iterations = 0)")

    def render(self, camera, light) -> dict[str, torch.Tensor]:
        return {"rgb": self.mean}

    def state_dict(self) -> dict[str, Any]:
        return {"mean": self.mean}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.mean = state["mean"]
