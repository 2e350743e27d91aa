"""The ground truth each official pipeline feeds its method, reproduced with `olatbench.datasets.colour`.

These helpers exist to check `Frame.load` against the official code paths and to score exactly as the
papers did. All return float32 (H, W, 3) in [0, 1] in the space the official method trains in. Each composites on
the frame's own background, ``Frame.background`` (set by the format's reader, the one place a scene's background is
chosen: ``datasets info`` prints it), which is also the background the official code is run with
(`olatbench.methods.official.runner.background_args`) and the native methods train on:

* NRHints scenes as read by the GS³ / SSD-GS loader: the straight-alpha sRGB PNG composited on the background in
  sRGB (black for real captures, white for NRHints' synthetic scenes, passed ``--white_background``), then
  ``np.array(x * 255, dtype=np.byte)`` → truncating 8-bit quantisation.
* GS³: the linear EXR composited on its background (white) *with the straight-alpha formula* ``rgb·a + bg·(1−a)``
  although the EXR is premultiplied (the loader's quirk: fractional-alpha edge pixels are darkened by a second
  multiplication by alpha), then a pure 2.2 gamma and 8-bit. ``alpha_quirk=False`` composites correctly.
* SSS-GS: ``PIL.convert("RGB")`` drops alpha, then the colour is multiplied by the alpha mask (on black, the
  format's background) in sRGB; no quantisation beyond the 8-bit file.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from olatbench.datasets import colour
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.records import Frame


def _stored(frame: Frame) -> tuple[np.ndarray, np.ndarray]:
    """The file's colour (as stored, premultiplied if the format is) and alpha (1 when absent)."""
    from olatbench.datasets.images import read_image

    if frame.image_path is None:
        raise DatasetError("this frame has no image (a camera path)", frame=frame.frame_id)
    pixels = read_image(frame.image_path)
    if pixels.shape[:2] != (frame.camera.height, frame.camera.width):
        raise DatasetError(f"image is {pixels.shape[1]}×{pixels.shape[0]} but the camera says "
                           f"{frame.camera.width}×{frame.camera.height}", path=frame.image_path, frame=frame.frame_id)
    rgb = np.repeat(pixels, 3, axis=2) if pixels.shape[2] == 1 else pixels[..., :3]
    alpha = pixels[..., 3] if pixels.shape[2] == 4 else np.ones(pixels.shape[:2], dtype=np.float32)
    return rgb, alpha


def nrhints_ground_truth(frame: Frame) -> np.ndarray:
    """sRGB PNG composited on the frame's background, truncated to 8 bits (GS³ / SSD-GS loader)."""
    rgb, alpha = _stored(frame)
    composited = colour.composite(rgb, alpha, frame.background, "straight")
    return colour.dequantize_8bit(colour.quantize_8bit(composited, "truncate"))


def gs3_ground_truth(frame: Frame, alpha_quirk: bool = True,
                     quantize: Literal["round", "truncate"] | None = "round") -> np.ndarray:
    """Linear EXR composited on the frame's background (white), gamma 2.2 encoded, clipped to [0, 1] and quantised
    to 8 bits (``quantize=None`` keeps the clipped floats)."""
    rgb, alpha = _stored(frame)
    mode = "straight" if alpha_quirk else "premultiplied"
    encoded = colour.gamma_encode(colour.composite(rgb, alpha, frame.background, mode))
    if quantize is None:
        return np.clip(encoded, 0.0, 1.0)
    return colour.dequantize_8bit(colour.quantize_8bit(encoded, quantize))


def sssgs_ground_truth(frame: Frame) -> np.ndarray:
    """sRGB colour times the alpha mask, composited on the frame's background (black), as the SSS-GS dataset class
    does."""
    rgb, alpha = _stored(frame)
    return colour.composite(rgb, alpha, frame.background, "straight")


GROUND_TRUTH = {"nrhints": nrhints_ground_truth, "gs3": gs3_ground_truth, "sssgs": sssgs_ground_truth}


def official_ground_truth(frame: Frame, format: str) -> np.ndarray:
    """The official ground truth of ``frame`` for a scene of ``format``."""
    try:
        return GROUND_TRUTH[format](frame)
    except KeyError:
        raise DatasetError(f"no official ground truth for format '{format}'; known: {', '.join(GROUND_TRUTH)}") \
            from None
