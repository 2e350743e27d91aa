"""A minimal external method: predicts the mean training image whatever the light (a constant baseline).

Install it with ``pip install -e examples/external_method`` and run ``olatbench run --method mean-image ...``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import torch

from olatbench.methods import Method, Views


@dataclass
class MeanImageConfig:
    iterations: int = 1  # the runner needs a length; one step computes the mean


class MeanImage(Method):
    """``rgb`` = the per-pixel mean of the training images (H, W, 3), in the training colour space."""

    name: ClassVar[str] = "mean-image"
    config_class: ClassVar[type] = MeanImageConfig
    presets: ClassVar[dict[str, dict[str, Any]]] = {}
    description: ClassVar[str] = "Example external method: the mean training image, blind to the light."

    def setup(self, train: Views, device, seed: int) -> None:
        self.images = torch.from_numpy(train.images).to(device)
        self.mean = torch.zeros_like(self.images[0])

    def train_step(self, step: int) -> dict[str, float]:
        self.mean = self.images.mean(dim=0)
        return {"loss": float((self.images - self.mean).abs().mean())}

    def render(self, camera, light) -> dict[str, torch.Tensor]:
        return {"rgb": self.mean}

    def state_dict(self) -> dict[str, Any]:
        return {"mean": self.mean}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.mean = state["mean"]
