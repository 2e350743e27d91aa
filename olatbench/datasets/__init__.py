"""OLAT datasets: one normalized record for NRHints, GS³ and SSS-GS, with numpy alone.

>>> from olatbench.datasets import load_scene
>>> scene = load_scene("path/to/scene")          # format auto-detected
>>> frame = scene.split("train")[0]
>>> image = frame.load(colourspace="srgb")      # composited on the official background

Importing this package never imports torch; the optional torch ``Dataset`` adapter
lives in `olatbench.datasets.torch_adapter`.
"""

from pathlib import Path

from olatbench.datasets.errors import DatasetError
from olatbench.datasets.records import Camera, Frame, LoadedImage, PointLight, Scene

__all__ = ["Camera", "DatasetError", "Frame", "LoadedImage", "PointLight", "Scene", "load_scene"]


def load_scene(path: str | Path, format: str | None = None) -> Scene:
    """Read one scene folder of NRHints, GS³ or SSS-GS (``format=None`` detects it). Raises
    `DatasetError`."""
    from olatbench.datasets.formats import detect_format, format_module

    path = Path(path)
    if not path.is_dir():
        raise DatasetError("scene folder not found", path=path)
    return format_module(format or detect_format(path)).read_scene(path)
