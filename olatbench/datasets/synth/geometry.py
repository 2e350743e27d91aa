"""The diagnostic geometry pass on disk: one multi-channel float EXR per frame with named channels.

Channels (see `render.GEOMETRY_CHANNELS`): ``A`` foreground coverage (object + ground), ``object``
object coverage, ``N.X``/``N.Y``/``N.Z`` world-space shading normal, ``Z`` OpenCV camera depth
(distance along the optical axis, world units; 0 where nothing was hit).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from olatbench.datasets.images import read_channels, write_image


def write_geometry(path: str | Path, channels: dict[str, np.ndarray]) -> Path:
    """Write (H, W) float arrays as one half-float EXR whose channel names are the dict keys
    (atomically)."""
    names = list(channels)
    stacked = np.stack([np.asarray(channels[n], dtype=np.float32) for n in names], axis=-1)
    return write_image(path, stacked, "half", channel_names=names)


def read_geometry(path: str | Path) -> dict[str, np.ndarray]:
    """Channel name -> (H, W) float32 array of a geometry EXR."""
    return read_channels(path)
