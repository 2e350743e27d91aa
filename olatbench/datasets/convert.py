"""Write a `Scene` in any supported format: ``datasets convert`` and the scene generator use this.

``pixels(frame)`` gives a frame's image as float32 (H, W, 4), **linear light, straight alpha**; each
format's writer converts it to what the real files hold (NRHints/SSS-GS: 8-bit sRGB straight PNG,
GS³: half-float linear premultiplied EXR). Cameras are written back in the JSON's OpenGL axes.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from olatbench.datasets.errors import DatasetError, OutputExistsError
from olatbench.datasets.formats import format_module, is_scene_folder
from olatbench.datasets.records import Frame, Scene

PixelSource = Callable[[Frame], np.ndarray]


def frame_pixels(frame: Frame) -> np.ndarray:
    """A frame's own image as linear straight RGBA float32 (H, W, 4); alpha 1 when the file has
    none."""
    image = frame.load(colourspace="linear", background=None)
    alpha = (
        image.alpha if image.alpha is not None else np.ones(image.rgb.shape[:2], dtype=np.float32)
    )
    return np.concatenate([image.rgb, alpha[..., None]], axis=2).astype(np.float32)


def _checked(pixels: PixelSource) -> PixelSource:
    """Wrap ``pixels`` so that a wrong shape or a non-finite value is a `DatasetError` naming the
    frame."""

    def checked(frame: Frame) -> np.ndarray:
        if frame.image_path is None and pixels is frame_pixels:
            raise DatasetError("frame has no image; pass pixels= to write it", frame=frame.frame_id)
        array = np.asarray(pixels(frame), dtype=np.float32)
        expected = (frame.camera.height, frame.camera.width, 4)
        if array.shape != expected:
            raise DatasetError(
                f"pixels are {array.shape}, expected {expected} (H, W, RGBA)", frame=frame.frame_id
            )
        if not np.all(np.isfinite(array)):
            raise DatasetError("pixels hold NaN or Inf", frame=frame.frame_id)
        return array

    return checked


def write_scene(
    scene: Scene,
    out_dir: str | Path,
    fmt: str,
    pixels: PixelSource | None = None,
    *,
    overwrite: bool = False,
) -> Path:
    """Write ``scene`` into ``out_dir`` in format ``fmt`` (``nrhints``, ``gs3`` or ``sssgs``);
    returns ``out_dir``.

    Frames without an image (``image_path=None``, e.g. a camera path or generated frames) need
    ``pixels``. Refuses to write inside the source tree, or over an existing scene unless
    ``overwrite``.
    """
    module = format_module(fmt)
    out_dir = Path(out_dir)
    source = Path(scene.root).resolve()
    if is_scene_folder(source) and out_dir.resolve().is_relative_to(source):
        raise DatasetError(
            "refusing to write inside the source dataset (trees are read-only)", path=out_dir
        )
    if is_scene_folder(out_dir) and not overwrite:
        raise OutputExistsError(
            "a scene already exists here; choose another folder or pass overwrite=True",
            path=out_dir,
        )
    out_dir.mkdir(parents=True, exist_ok=True)
    return module.write_scene(scene, out_dir, _checked(pixels or frame_pixels))
