"""The diagnostic geometry pass on disk: one multi-channel float EXR per frame with named channels.

Channels (see `render.GEOMETRY_CHANNELS`): ``A`` foreground coverage (object + ground), ``object``
object coverage, ``N.X``/``N.Y``/``N.Z`` world-space shading normal, ``Z`` OpenCV camera depth
(distance along the optical axis, world units; 0 where nothing was hit).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from olatbench.atomic import atomic_path
from olatbench.datasets.errors import DatasetError


def _oiio():
    import OpenImageIO as oiio

    return oiio


def write_geometry(path: str | Path, channels: dict[str, np.ndarray]) -> Path:
    """Write (H, W) float arrays as one half-float EXR whose channel names are the dict keys (atomically)."""
    oiio = _oiio()
    path = Path(path)
    names = list(channels)
    stacked = np.stack([np.asarray(channels[n], dtype=np.float32) for n in names], axis=-1)
    height, width, count = stacked.shape
    spec = oiio.ImageSpec(width, height, count, "half")
    spec.channelnames = tuple(names)
    spec.attribute("compression", "zip")
    spec.attribute("DateTime", "")  # no time stamp: the same pixels give the same bytes
    with atomic_path(path) as temporary:
        output = oiio.ImageOutput.create(str(temporary))
        if output is None or not output.open(str(temporary), spec):
            raise OSError(f"{path}: cannot write the geometry pass ({oiio.geterror()})")
        ok = output.write_image(np.ascontiguousarray(stacked))
        output.close()
        if not ok:
            raise OSError(f"{path}: cannot write the geometry pass ({output.geterror()})")
    return path


def read_geometry(path: str | Path) -> dict[str, np.ndarray]:
    """Channel name -> (H, W) float32 array of a geometry EXR."""
    oiio = _oiio()
    path = Path(path)
    image = oiio.ImageInput.open(str(path))
    if image is None:
        raise DatasetError(f"cannot open the geometry pass ({oiio.geterror()})", path=path)
    try:
        spec = image.spec()
        pixels = np.asarray(image.read_image(0, 0, 0, spec.nchannels, "float"), dtype=np.float32)
        names = list(spec.channelnames)
    finally:
        image.close()
    pixels = pixels.reshape(spec.height, spec.width, spec.nchannels)
    return {name: pixels[..., i] for i, name in enumerate(names)}
