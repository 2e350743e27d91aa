"""The ground truth each official pipeline feeds its method, reproduced with
`olatbench.datasets.colour`.

Each format module carries its own (``official_ground_truth(frame)``); this module picks the
format's. They exist to check `Frame.load` against the official code paths and to score exactly as
the papers did. All return float32 (H, W, 3) in [0, 1] in the space the official method trains in.
Each composites on the frame's own background, ``Frame.background`` (set by the format's reader, the
one place a scene's background is chosen: ``datasets info`` prints it), which is also the background
the official code is run with (`olatbench.methods.official.runner.background_args`) and the native
methods train on:

* NRHints scenes as read by the GS³ / SSD-GS loader: the straight-alpha sRGB PNG composited on the
  background in sRGB (black for real captures, white for NRHints' synthetic scenes, passed
  ``--white_background``), then ``np.array(x * 255, dtype=np.byte)`` → truncating 8-bit
  quantisation.
* GS³: the linear EXR composited on its background (white) *with the straight-alpha formula*
  ``rgb·a + bg·(1−a)`` although the EXR is premultiplied (the loader's quirk: fractional-alpha edge
  pixels are darkened by a second multiplication by alpha), then a pure 2.2 gamma and 8-bit.
  ``alpha_quirk=False`` composites correctly.
* SSS-GS: ``PIL.convert("RGB")`` drops alpha, then the colour is multiplied by the alpha mask
  (on black, the format's background) in sRGB; no quantisation beyond the 8-bit file.
"""

from __future__ import annotations

import numpy as np

from olatbench.datasets.errors import DatasetError
from olatbench.datasets.formats import FORMATS
from olatbench.datasets.records import Frame


def official_ground_truth(frame: Frame, format: str) -> np.ndarray:
    """The official ground truth of ``frame`` for a scene of ``format`` (the format module's)."""
    if format not in FORMATS:
        raise DatasetError(
            f"no official ground truth for format '{format}'; known: {', '.join(FORMATS)}"
        )
    return FORMATS[format].official_ground_truth(frame)
