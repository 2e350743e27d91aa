"""The viewer's environment-map mode, its settings (numpy only): which map, its rotation and
exposure, how many samples, and how the refinement is cut into passes (docs/viewer.md).

The maps a tab can choose are the built-in ones (`olatbench.datasets.lighting.BUILT_IN_MAPS`) and
the ``.exr`` / ``.hdr`` files given to ``olatbench view --envmap`` when the server starts: a tab
sends a map's label, matched against that menu, never opened as a path (as jobs are chosen: a
browser on another machine cannot make the server read a file). Every bad setting is a
`SettingsError` of one line that names the field.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from olatbench.datasets.errors import DatasetError
from olatbench.datasets.lighting import BUILT_IN_MAPS, Lighting, environment_lighting, load_map
from olatbench.datasets.lighting.envmap import MAP_SUFFIXES

POINT_MODE, ENVIRONMENT_MODE = "point light", "environment map"
MODES = (POINT_MODE, ENVIRONMENT_MODE)
# K: the samples a view converges to (as `olatbench render --envmap`'s default)
DEFAULT_SAMPLES = 64
MAX_SAMPLES = 4096
PREVIEW_SAMPLES = 4  # samples of the image shown while the view moves
BATCH_SAMPLES = 8  # samples added per refinement pass once the view is still
ROTATION_RANGE = (-180.0, 180.0)  # degrees
EXPOSURE_RANGE = (-8.0, 8.0)  # stops


class SettingsError(ValueError):
    """A bad environment-map setting: one line naming the field."""


@dataclass(frozen=True)
class EnvironmentSettings:
    """What an environment-map view shows: ``source`` a built-in map's name or a file's path,
    ``label`` its name in the menu, ``rotation`` degrees about the scene's vertical, ``exposure``
    stops, ``samples`` the sample count ``K`` a still view converges to, ``seed`` the sampling seed
    (the lighting of `lighting`)."""

    source: str
    label: str
    rotation: float = 0.0
    exposure: float = 0.0
    samples: int = DEFAULT_SAMPLES
    seed: int = 0

    def lighting(self) -> Lighting:
        """The lighting ``olatbench render --envmap SOURCE --samples K`` renders (same samples for
        the same seed), turned and scaled."""
        return environment_lighting(
            self.source, self.samples, self.seed, self.rotation, self.exposure
        )


def map_menu(files: Sequence[str | Path] = ()) -> dict[str, str]:
    """The maps a tab can choose, label -> source: the built-in maps, then each file (labelled by
    its name, or its path when two share a name), checked by reading it (a `SettingsError` naming
    the file otherwise)."""
    menu = {name: name for name in BUILT_IN_MAPS}
    names = [Path(f).name for f in files]
    for file, name in zip(files, names, strict=True):
        path = Path(file)
        if path.suffix.lower() not in MAP_SUFFIXES:
            raise SettingsError(f"--envmap {file}: an environment map is an .exr or .hdr file")
        try:
            load_map(str(path))
        except DatasetError as error:
            raise SettingsError(f"--envmap {error}") from None
        label = name if names.count(name) == 1 and name not in BUILT_IN_MAPS else str(path)
        menu[label] = str(path.resolve())
    return menu


def parse_settings(
    menu: Mapping[str, str], label: object, rotation: object, exposure: object, samples: object
) -> EnvironmentSettings:
    """The settings of a tab's controls (values as the tab sent them); a `SettingsError` naming the
    field."""
    if not isinstance(label, str) or label not in menu:
        raise SettingsError(
            f"map {label!r}: not in the menu ({', '.join(menu)}); other files are given to "
            "'olatbench view --envmap FILE'"
        )
    return EnvironmentSettings(
        menu[label],
        label,
        _number("rotation °", rotation, *ROTATION_RANGE),
        _number("exposure (stops)", exposure, *EXPOSURE_RANGE),
        int(_number("samples", samples, 1, MAX_SAMPLES, integer=True)),
    )


def _number(field: str, value: object, low: float, high: float, integer: bool = False) -> float:
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise SettingsError(f"{field}: {value!r} is not a number") from None
    if not (math.isfinite(number) and low <= number <= high):
        raise SettingsError(f"{field}: {value!r} is outside [{low:g}, {high:g}]")
    if integer and number != int(number):
        raise SettingsError(f"{field}: {value!r} is not a whole number")
    return number


def refinement_passes(
    total: int, preview: int = PREVIEW_SAMPLES, batch: int = BATCH_SAMPLES
) -> int:
    """Full-resolution passes of a still view with ``total`` probes: the first renders ``preview``
    of them (a quick first image), each further pass ``batch`` more, until all are done."""
    if total < 1 or preview < 1 or batch < 1:
        raise ValueError(
            f"total, preview and batch must be at least 1, not {total}, {preview}, {batch}"
        )
    return 1 + math.ceil(max(total - preview, 0) / batch)


def pass_size(done: int, preview: int = PREVIEW_SAMPLES, batch: int = BATCH_SAMPLES) -> int:
    """Probes the next pass renders when ``done`` are done (`refinement_passes`)."""
    return preview if done == 0 else batch


__all__ = [
    "BATCH_SAMPLES",
    "DEFAULT_SAMPLES",
    "ENVIRONMENT_MODE",
    "EXPOSURE_RANGE",
    "MAX_SAMPLES",
    "MODES",
    "POINT_MODE",
    "PREVIEW_SAMPLES",
    "ROTATION_RANGE",
    "EnvironmentSettings",
    "SettingsError",
    "map_menu",
    "parse_settings",
    "pass_size",
    "refinement_passes",
]
