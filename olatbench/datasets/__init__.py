"""OLAT datasets: one normalized record for NRHints, GS³ and SSS-GS, with numpy alone.

>>> from olatbench.datasets import load_scene
>>> scene = load_scene("path/to/scene")          # format auto-detected
>>> frame = scene.split("train")[0]
>>> image = frame.load(colourspace="srgb")      # composited on the official background

Importing this package never imports torch; the optional torch ``Dataset`` adapter
lives in `olatbench.datasets.torch_adapter`.
"""

from olatbench.datasets.errors import DatasetError
from olatbench.datasets.records import Camera, Frame, LoadedImage, PointLight, Scene

__all__ = ["Camera", "DatasetError", "Frame", "LoadedImage", "PointLight", "Scene"]
