"""``torchvision.utils.save_image`` (and the ``make_grid`` it uses) without torchvision.

The authors' ``render.py`` writes every render with ``torchvision.utils.save_image(image [3, H, W],
path)``, and PyPI's torchvision does not import beside the local CPU build of torch (``operator
torchvision::nms does not exist``). This is torchvision's arithmetic (``make_grid`` with ``nrow=8,
padding=2, pad_value=0``, then ``x·255 + 0.5`` clamped to [0, 255] and truncated to uint8, written
by Pillow); ``normalize``/``value_range``/ ``scale_each`` are not implemented and raise
`NotImplementedError`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch


def make_grid(
    tensor: torch.Tensor | list[torch.Tensor],
    nrow: int = 8,
    padding: int = 2,
    normalize: bool = False,
    value_range: tuple[float, float] | None = None,
    scale_each: bool = False,
    pad_value: float = 0.0,
) -> torch.Tensor:
    """torchvision's ``make_grid``: [B, C, H, W] (or [C, H, W], [H, W], a list) -> one [C, H', W']
    image."""
    if normalize or value_range is not None or scale_each:
        raise NotImplementedError(
            "torchvision stand-in (olatbench CPU): make_grid/save_image with normalize, "
            "value_range or scale_each is not implemented"
        )
    if isinstance(tensor, list):
        tensor = torch.stack(tensor, dim=0)
    if tensor.dim() == 2:
        tensor = tensor.unsqueeze(0)
    if tensor.dim() == 3:
        if tensor.size(0) == 1:
            tensor = torch.cat((tensor, tensor, tensor), 0)
        tensor = tensor.unsqueeze(0)
    if tensor.dim() == 4 and tensor.size(1) == 1:
        tensor = torch.cat((tensor, tensor, tensor), 1)
    if tensor.size(0) == 1:
        return tensor.squeeze(0)
    count = tensor.size(0)
    xmaps = min(nrow, count)
    ymaps = math.ceil(float(count) / xmaps)
    height, width = int(tensor.size(2) + padding), int(tensor.size(3) + padding)
    grid = tensor.new_full(
        (tensor.size(1), height * ymaps + padding, width * xmaps + padding), pad_value
    )
    k = 0
    for y in range(ymaps):
        for x in range(xmaps):
            if k >= count:
                break
            grid[
                :, y * height + padding : (y + 1) * height, x * width + padding : (x + 1) * width
            ] = tensor[k]
            k += 1
    return grid


@torch.no_grad()
def save_image(
    tensor: torch.Tensor | list[torch.Tensor], fp: Any, format: str | None = None, **kwargs: Any
) -> None:
    """torchvision's ``save_image``: values in [0, 1] -> an 8-bit image file (module docstring)."""
    from PIL import Image

    grid = make_grid(tensor, **kwargs)
    array = grid.mul(255).add_(0.5).clamp_(0, 255).permute(1, 2, 0).to("cpu", torch.uint8).numpy()
    Image.fromarray(np.ascontiguousarray(array)).save(fp, format=format)
