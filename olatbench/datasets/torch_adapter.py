"""A torch ``Dataset`` over frames (imports torch; `olatbench.datasets` itself never does).

>>> from olatbench.datasets import load_scene
>>> from olatbench.datasets.torch_adapter import FrameDataset
>>> data = FrameDataset(load_scene("data/nrhints/Pixiu").split("train"), colourspace="srgb")
>>> item = data[0]  # image (H, W, 3), alpha (H, W), K (3, 3), c2w/w2c (4, 4) OpenCV, light_pos (3,)
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch.utils.data import Dataset

from olatbench.datasets.records import Frame


class FrameDataset(Dataset):
    """Frames as dicts of float32 tensors, loaded on access.

    ``image`` (H, W, 3) in ``colourspace`` composited on ``background`` ("official", a colour or
    None for straight colour), ``alpha`` (H, W) (ones when the file has none), ``K`` (3, 3) pixels
    with centres at +0.5, ``c2w`` and ``w2c`` (4, 4) OpenCV axes, ``light_pos`` (3,),
    ``light_intensity`` (3,), ``index`` and ``frame_id``. ``resolution`` = (width, height) resizes
    the image and scales ``K`` to match.
    """

    def __init__(
        self,
        frames: Sequence[Frame],
        colourspace: str = "srgb",
        background: np.ndarray | float | str | None = "official",
        resolution: tuple[int, int] | None = None,
    ) -> None:
        self.frames = list(frames)
        self.colourspace = colourspace
        self.background = background
        self.resolution = resolution

    def __len__(self) -> int:
        return len(self.frames)

    def __getitem__(self, index: int) -> dict[str, object]:
        frame = self.frames[index]
        camera = frame.camera if self.resolution is None else frame.camera.resized(*self.resolution)
        image = frame.load(
            colourspace=self.colourspace, background=self.background, resolution=self.resolution
        )
        alpha = (
            image.alpha
            if image.alpha is not None
            else np.ones(image.rgb.shape[:2], dtype=np.float32)
        )

        def tensor(array: np.ndarray) -> torch.Tensor:
            return torch.from_numpy(np.ascontiguousarray(array, dtype=np.float32))

        return {
            "image": tensor(image.rgb),
            "alpha": tensor(alpha),
            "K": tensor(camera.K),
            "c2w": tensor(camera.c2w),
            "w2c": tensor(camera.w2c()),
            "light_pos": tensor(frame.light.position),
            "light_intensity": tensor(frame.light.intensity),
            "index": index,
            "frame_id": frame.frame_id,
        }
