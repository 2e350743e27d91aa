"""The normalized per-image record shared by every format reader.

Conventions (see `olatbench.datasets.cameras`):

* ``Camera.K`` is 3×3 in pixels, pixel centres at +0.5; ``Camera.c2w`` is 4×4
  camera-to-world in OpenCV axes (x right, y down, z forward), world units of the dataset.
* ``PointLight.position`` is in the same world frame and units; its ``intensity`` is RGB
  radiant intensity with inverse-square falloff, ``intensity_known=False`` when the
  format does not store it (then it is 1).
* Images are stored in ``Frame.colourspace`` with ``Frame.alpha_mode`` alpha.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.datasets import colour
from olatbench.datasets.cameras import scale_intrinsics
from olatbench.datasets.errors import DatasetError

Split = str  # "train", "val", "test", "eval" (SSS-GS), or "path" (a camera path without images)


@dataclass(frozen=True, eq=False)
class Camera:
    """A pinhole camera: ``K`` (3, 3) pixels, ``c2w`` (4, 4) OpenCV axes, image size in pixels."""

    K: np.ndarray
    c2w: np.ndarray
    width: int
    height: int
    near: float | None = None
    far: float | None = None

    @property
    def fx(self) -> float:
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        return float(self.K[1, 2])

    @property
    def position(self) -> np.ndarray:
        """Camera centre in world coordinates (3,)."""
        return np.asarray(self.c2w[:3, 3], dtype=np.float64)

    def w2c(self) -> np.ndarray:
        """World-to-camera (4, 4) in OpenCV axes."""
        return np.linalg.inv(self.c2w)

    def resized(self, width: int, height: int) -> Camera:
        """The same camera for an image resized to ``width`` × ``height``."""
        K = scale_intrinsics(self.K, width / self.width, height / self.height)
        return replace(self, K=K, width=int(width), height=int(height))


@dataclass(frozen=True, eq=False)
class PointLight:
    """A point light: world ``position`` (3,), RGB ``intensity`` (3,), whether the intensity is
    known."""

    position: np.ndarray
    intensity: np.ndarray = field(default_factory=lambda: np.ones(3))
    intensity_known: bool = False

    def irradiance_scale(self, points: np.ndarray) -> np.ndarray:
        """Inverse-square falloff ``intensity / d²`` at world points (N, 3) -> (N, 3)."""
        d2 = np.sum(
            (np.asarray(points, dtype=np.float64) - self.position) ** 2, axis=-1, keepdims=True
        )
        return self.intensity / d2


@dataclass(frozen=True)
class LoadedImage:
    """Pixels of one frame: ``rgb`` (H, W, 3) float32 in ``colourspace``; ``alpha`` (H, W) or None.

    When a background was applied ``rgb`` is composited; otherwise it is straight
    (not premultiplied). Both may be views of one decoded (H, W, 4) buffer (``rgb`` then has a row
    stride of 4 channels); ``np.ascontiguousarray`` gives a packed copy where one is needed.
    """

    rgb: np.ndarray
    alpha: np.ndarray | None
    colourspace: str


@dataclass(frozen=True, eq=False)
class Frame:
    """One image of an OLAT capture: camera, light and how to read its pixels."""

    scene: str
    split: Split
    frame_id: str
    image_path: Path | None
    camera: Camera
    light: PointLight
    colourspace: colour.ColourSpace = "srgb"
    alpha_mode: colour.AlphaMode = "straight"
    # official, stored colour space
    background: np.ndarray = field(default_factory=lambda: np.zeros(3))
    extras: Mapping[str, Any] = field(default_factory=dict)

    def load(
        self,
        colourspace: colour.ColourSpace | None = None,
        background: np.ndarray | float | str | None = "official",
        resolution: tuple[int, int] | None = None,
    ) -> LoadedImage:
        """Read the pixels.

        ``colourspace``: target space (default: as stored). ``background``: ``"official"``
        (the dataset's), a colour (3,) or scalar in the *target* space, or ``None`` to keep
        straight colour and alpha. ``resolution``: (width, height) to resize to with
        area averaging (use `Camera.resized` for the matching camera). Compositing happens in
        the stored colour space, as the official pipelines do.
        """
        from olatbench.datasets.images import read_image, resize_image

        if self.image_path is None:
            raise DatasetError("this frame has no image (a camera path)", frame=self.frame_id)
        target = colourspace or self.colourspace
        try:
            pixels = read_image(self.image_path)
        except DatasetError as error:  # name the frame too
            raise DatasetError(
                error.message, path=error.path, frame=self.frame_id, key=error.key
            ) from None
        channels = pixels.shape[2]
        if channels not in (1, 3, 4):
            raise DatasetError(
                f"expected 1, 3 or 4 channels, found {channels}",
                path=self.image_path,
                frame=self.frame_id,
            )
        if pixels.shape[:2] != (self.camera.height, self.camera.width):
            raise DatasetError(
                f"image is {pixels.shape[1]}×{pixels.shape[0]} but the camera says "
                f"{self.camera.width}×{self.camera.height}",
                path=self.image_path,
                frame=self.frame_id,
            )
        if not np.all(np.isfinite(pixels)):
            raise DatasetError(
                "image holds NaN or Inf pixels", path=self.image_path, frame=self.frame_id
            )
        # Work in place on the freshly decoded buffer: rgb stays a view of it
        # (no extra full-size copies).
        if channels == 1:
            pixels = np.repeat(pixels, 3, axis=2)
        if resolution is not None:
            pixels = resize_image(pixels, *resolution)
        rgb = pixels[..., :3]
        # kept aside: the colour pass below spans all 4
        alpha = pixels[..., 3].copy() if channels == 4 else None
        if isinstance(background, str):
            if background != "official":
                raise ValueError(
                    f"background must be 'official', a colour or None, not {background!r}"
                )
            background = colour.convert_colourspace(self.background, self.colourspace, target)
        if background is not None and alpha is not None:
            stored_bg = colour.convert_colourspace(
                np.broadcast_to(np.asarray(background, np.float32), (3,)), target, self.colourspace
            )
            colour.composite(rgb, alpha, stored_bg, self.alpha_mode, out=rgb)
        elif alpha is not None and self.alpha_mode == "premultiplied":
            rgb[...] = colour.unpremultiply(rgb, alpha)
        # Element-wise, so converting the whole contiguous buffer (4th channel discarded) is the
        # fast path.
        colour.convert_colourspace(pixels, self.colourspace, target, out=pixels)
        return LoadedImage(rgb=rgb.astype(np.float32, copy=False), alpha=alpha, colourspace=target)


@dataclass(eq=False)
class Scene:
    """A scene of one dataset: frames per split, its format, root folder and official background."""

    name: str
    format: str
    root: Path
    frames: dict[Split, list[Frame]]
    background: np.ndarray = field(default_factory=lambda: np.zeros(3))
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def splits(self) -> list[Split]:
        return [split for split, frames in self.frames.items() if frames]

    def split(self, name: Split) -> list[Frame]:
        """The frames of one split; a `DatasetError` listing the available splits otherwise."""
        if name not in self.frames:
            raise DatasetError(
                f"no split '{name}'; available: {', '.join(self.splits) or 'none'}", path=self.root
            )
        return self.frames[name]

    def __iter__(self):
        for frames in self.frames.values():
            yield from frames
