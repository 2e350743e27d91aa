"""Feed olatbench frames to a PyTorch training loop through a standard DataLoader.

python examples/loaders_torch_dataloader.py path/to/scene
"""

from __future__ import annotations

import sys

from torch.utils.data import DataLoader

from olatbench.datasets import load_scene
from olatbench.datasets.torch_adapter import FrameDataset


def main(root: str, batch_size: int = 2) -> None:
    scene = load_scene(root)
    dataset = FrameDataset(scene.split("train"), colourspace="srgb", background="official")
    for batch in DataLoader(dataset, batch_size=batch_size, shuffle=True, num_workers=0):
        # image (B, H, W, 3), K (B, 3, 3) pixels, w2c (B, 4, 4) OpenCV axes, light_pos (B, 3) world
        # units
        print(tuple(batch["image"].shape), tuple(batch["K"].shape), tuple(batch["light_pos"].shape))


if __name__ == "__main__":
    main(sys.argv[1])
