"""Format readers and writers, one module per format, and auto-detection.

Each module has ``FORMAT_NAME``, ``DISPLAY_COLOURSPACE`` (the space the format's official code trains and
scores in), ``detect(root) -> bool``, ``read_scene(root, errors=None) -> Scene`` and
``write_scene(scene, out_dir, pixels) -> Path``.
"""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

from olatbench.datasets.errors import DatasetError
from olatbench.datasets.formats import gs3, nrhints, sssgs

FORMATS: dict[str, ModuleType] = {module.FORMAT_NAME: module for module in (sssgs, gs3, nrhints)}


def format_module(name: str) -> ModuleType:
    """The module of format ``name``."""
    try:
        return FORMATS[name]
    except KeyError:
        raise DatasetError(f"unknown format '{name}'; known formats: {', '.join(FORMATS)}") from None


def display_colourspace(name: str) -> str:
    """The colour space format ``name`` is trained and scored in (``gamma22`` for GS³, ``srgb`` otherwise):
    the one source for suites, the runner and ``olatbench evaluate``."""
    return format_module(name).DISPLAY_COLOURSPACE


def detect_format(root: str | Path) -> str:
    """The format of a scene folder; a `DatasetError` saying what was looked for otherwise."""
    root = Path(root)
    if not root.is_dir():
        raise DatasetError("not a folder", path=root)
    for name, module in FORMATS.items():
        if module.detect(root):
            return name
    raise DatasetError("no known dataset format here (expected transforms_train.json / transforms_test.json "
                       "of NRHints, GS³ or SSS-GS)", path=root)


def is_scene_folder(root: str | Path) -> bool:
    """Whether ``root`` holds a scene of any known format (a malformed one counts)."""
    root = Path(root)
    return root.is_dir() and any((root / name).is_file() for name in
                                 ("transforms_train.json", "transforms_test.json", "transforms_val.json"))
