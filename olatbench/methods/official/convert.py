"""olatbench's scene -> the files an official loader reads, and its renders -> olatbench's frame ids.

The converted scene holds the suite's train split as ``train`` and its test split as ``test`` (and, for loaders
that open ``transforms_val.json``, the test frames again as ``val``), in the source order, at the job's
resolution (cameras resized with `Camera.resized`, images area-resized by `Frame.load`). The official loaders
enumerate a split in file order, so the render of test frame ``index`` belongs to the ``index``-th test frame of
the source scene.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from olatbench.datasets.convert import write_scene
from olatbench.datasets.records import Frame, Scene
from olatbench.methods.official.code import OfficialCode


def converted_scene(source: Scene, train_split: str, test_split: str, resolution: tuple[int, int] | None,
                    with_val: bool = False) -> tuple[Scene, dict[int, Frame]]:
    """The scene to write (splits renamed ``train`` / ``test`` [/ ``val``], cameras resized) and, for the
    pixels, each written frame's source frame (by ``id``)."""
    originals: dict[int, Frame] = {}

    def resized(frame: Frame) -> Frame:
        camera = frame.camera.resized(*resolution) if resolution else frame.camera
        copy = dataclasses.replace(frame, camera=camera)
        originals[id(copy)] = frame
        return copy

    frames = {"train": [resized(f) for f in source.split(train_split)],
              "test": [resized(f) for f in source.split(test_split)]}
    if with_val:
        frames["val"] = [resized(f) for f in source.split(test_split)]
    scene = Scene(name=source.name, format=source.format, root=source.root, frames=frames,
                  background=source.background, metadata=dict(source.metadata))
    return scene, originals


def write_for_code(code: OfficialCode, source: Scene, out_dir: Path, suite: str, train_split: str,
                   test_split: str, resolution: tuple[int, int] | None) -> Path:
    """Write ``source`` where and how ``code``'s loader reads it for ``suite`` (replacing an earlier copy)."""
    scene, originals = converted_scene(source, train_split, test_split, resolution, code.needs_val_split)

    def pixels(frame: Frame) -> np.ndarray:
        image = originals[id(frame)].load(colourspace="linear", background=None, resolution=resolution)
        alpha = image.alpha if image.alpha is not None else np.ones(image.rgb.shape[:2], np.float32)
        return np.concatenate([image.rgb, alpha[..., None]], axis=2).astype(np.float32)

    return write_scene(scene, out_dir, code.data_format(suite), pixels, overwrite=True)


def render_paths(code: OfficialCode, frame_ids: list[str], values: Mapping[str, object]) -> dict[str, Path]:
    """``{frame id: where code's render script writes that test frame}`` (``{index}`` = position in the split)."""
    return {frame_id: Path(code.renders.format_map({**values, "index": index}))
            for index, frame_id in enumerate(frame_ids)}
