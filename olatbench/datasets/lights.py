"""A light named on the command line: a training frame's light by its index, or a position in world
units."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from olatbench.datasets.records import PointLight


def parse_light(text: str, lights: Sequence[PointLight]) -> PointLight:
    """``"12"``: ``lights[12]`` (the light of training frame 12, in the training split's order);
    ``"x,y,z"``: a point light at that world position (scene units) with ``lights[0]``'s intensity.
    A `ValueError` naming the valid indices otherwise."""
    parts = [part.strip() for part in text.split(",")]
    if len(parts) == 1 and parts[0].isdigit():
        index = int(parts[0])
        if index >= len(lights):
            raise ValueError(
                f"light {index}: the training split has {len(lights)} frames (lights 0 … "
                f"{len(lights) - 1})"
            )
        return lights[index]
    try:
        position = np.array([float(part) for part in parts]) if len(parts) == 3 else None
    except ValueError:
        position = None
    if position is None or not np.all(np.isfinite(position)):
        raise ValueError(
            f"light {text!r}: expected a training light index (0 … {len(lights) - 1}) or a "
            "position x,y,z"
        )
    return replace(lights[0], position=position)


__all__ = ["parse_light"]
