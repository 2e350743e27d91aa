"""Format readers and writers, one module per format, and auto-detection.

Each format module satisfies `FormatModule` (checked by tests/test_datasets_formats.py): it reads
and writes its scenes, names its display colour space, its suite settings (``SUITE_DEFAULTS``) and
its official ground truth, so a new format is one module and its line in `FORMATS`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Protocol, cast

import numpy as np

from olatbench.datasets.errors import DatasetError
from olatbench.datasets.formats import gs3, nrhints, sssgs
from olatbench.datasets.formats._suite import SuiteDefaults

if TYPE_CHECKING:
    from olatbench.datasets.records import Frame, Scene


class FormatModule(Protocol):
    """What a format module provides (a module, typed structurally)."""

    FORMAT_NAME: str  # the name suites and ``--format`` use
    DISPLAY_COLOURSPACE: str  # the space the format's official code trains and scores in
    # the paper's scenes and aliases, resolution, iterations, protocol
    SUITE_DEFAULTS: SuiteDefaults

    def detect(self, root: Path) -> bool:
        """Whether ``root`` holds a scene of this format."""
        ...

    def read_scene(self, root: Path, errors: list[DatasetError] | None = None) -> Scene:
        """The scene of ``root``; with ``errors`` given, problems are collected there instead of
        raised."""
        ...

    def write_scene(
        self, scene: Scene, out_dir: Path, pixels: Callable[[Frame], np.ndarray]
    ) -> Path:
        """Write ``scene`` in this format (``pixels(frame)`` gives each image) and return
        ``out_dir``."""
        ...

    def official_ground_truth(self, frame: Frame) -> np.ndarray:
        """The image (H, W, 3) float32 the format's official loader feeds its method
        (`olatbench.datasets.official`)."""
        ...


#: The formats, in the order `detect_format` tries them (the most specific first).
FORMATS: dict[str, FormatModule] = {
    module.FORMAT_NAME: cast(FormatModule, module) for module in (sssgs, gs3, nrhints)
}


def format_module(name: str) -> FormatModule:
    """The module of format ``name``."""
    try:
        return FORMATS[name]
    except KeyError:
        raise DatasetError(
            f"unknown format '{name}'; known formats: {', '.join(FORMATS)}"
        ) from None


def display_colourspace(name: str) -> str:
    """The colour space format ``name`` is trained and scored in (``gamma22`` for GS³, ``srgb``
    otherwise): the one source for suites, the runner and ``olatbench evaluate``."""
    return format_module(name).DISPLAY_COLOURSPACE


def detect_format(root: str | Path) -> str:
    """The format of a scene folder; a `DatasetError` saying what was looked for otherwise."""
    root = Path(root)
    if not root.is_dir():
        raise DatasetError("not a folder", path=root)
    for name, module in FORMATS.items():
        if module.detect(root):
            return name
    raise DatasetError(
        "no known dataset format here (expected transforms_train.json / transforms_test.json "
        "of NRHints, GS³ or SSS-GS)",
        path=root,
    )


def is_scene_folder(root: str | Path) -> bool:
    """Whether ``root`` holds a scene of any known format (a malformed one counts)."""
    root = Path(root)
    return root.is_dir() and any(
        (root / name).is_file()
        for name in ("transforms_train.json", "transforms_test.json", "transforms_val.json")
    )
