"""Lighting files: JSON in and out, validated (one `DatasetError` naming the file and the field).

Format (docs/relighting.md)::

    {"samples": 64, "seed": 0,
     "lights": [
       {"type": "point", "position": [x, y, z], "intensity": [r, g, b]},
       {"type": "directional", "direction": [x, y, z], "irradiance": [r, g, b]},
       {"type": "sphere", "centre": [x, y, z], "radius": 0.5, "intensity": [r, g, b],
        "samples": 16},
       {"type": "rect", "centre": [x, y, z], "u": [x, y, z], "v": [x, y, z],
        "intensity": [r, g, b]},
       {"type": "envmap", "map": "studio", "rotation": 90, "exposure": -1, "up": [0, 0, 1],
        "samples": 256}]}

Colours (``intensity``, ``irradiance``) are three non-negative numbers or one (grey); ``direction``
points from the scene towards the light; ``samples``, ``rotation``, ``exposure`` and ``up`` are
optional; ``map`` is a built-in name (`olatbench.datasets.lighting.envmap.BUILT_IN_MAPS`) or an
.exr/.hdr file, relative to the lighting file's folder.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.atomic import write_json
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.jsontext import parse_json
from olatbench.datasets.lighting.envmap import BUILT_IN_MAPS
from olatbench.datasets.lighting.sources import (
    DEFAULT_SAMPLES,
    DirectionalLight,
    EnvironmentMap,
    Lighting,
    LightSource,
    RectLight,
    SphereLight,
)
from olatbench.datasets.records import PointLight

# type -> (required, optional) fields
FIELDS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "point": (("position", "intensity"), ()),
    "directional": (("direction", "irradiance"), ()),
    "sphere": (("centre", "radius", "intensity"), ("samples",)),
    "rect": (("centre", "u", "v", "intensity"), ("samples",)),
    "envmap": (("map",), ("rotation", "exposure", "up", "samples")),
}


class _Fields:
    """Reads one object's fields, each error a `DatasetError` naming the file and the key path."""

    def __init__(self, data: Any, path: Path | None, where: str) -> None:
        if not isinstance(data, Mapping):
            raise DatasetError(
                f"expected an object, found {type(data).__name__}", path=path, key=where or None
            )
        self.data, self.path, self.where = data, path, where

    def key(self, name: str) -> str:
        return f"{self.where}.{name}" if self.where else name

    def fail(self, name: str, message: str) -> DatasetError:
        return DatasetError(message, path=self.path, key=self.key(name))

    def number(self, name: str, default: float | None = None, positive: bool = False) -> float:
        value = self.data.get(name, default)
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise self.fail(name, f"expected a finite number, found {value!r}")
        if positive and not value > 0:
            raise self.fail(name, f"must be > 0, not {value}")
        return float(value)

    def count(self, name: str, default: int | None = None) -> int | None:
        value = self.data.get(name, default)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise self.fail(name, f"expected a whole number ≥ 1, found {value!r}")
        return int(value)

    def vector(self, name: str, unit: bool = False) -> np.ndarray:
        value = self.data.get(name)
        if not (
            isinstance(value, list)
            and len(value) == 3
            and all(
                isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                for v in value
            )
        ):
            raise self.fail(name, f"expected three finite numbers [x, y, z], found {value!r}")
        vector = np.asarray(value, dtype=np.float64)
        if unit:
            norm = np.linalg.norm(vector)
            if not norm > 0.0:
                raise self.fail(name, "must not be the zero vector")
            vector = vector / norm
        return vector

    def colour(self, name: str) -> np.ndarray:
        value = self.data.get(name)
        if isinstance(value, int | float) and not isinstance(value, bool):
            value = [value] * 3
        if not (
            isinstance(value, list)
            and len(value) == 3
            and all(
                isinstance(v, int | float)
                and not isinstance(v, bool)
                and math.isfinite(v)
                and v >= 0
                for v in value
            )
        ):
            raise self.fail(
                name, f"expected a non-negative number or three [r, g, b], found {value!r}"
            )
        return np.asarray(value, dtype=np.float64)

    def check_keys(self, allowed: tuple[str, ...], required: tuple[str, ...]) -> None:
        for name in required:
            if name not in self.data:
                raise self.fail(name, "missing")
        for name in self.data:
            if name not in allowed:
                raise self.fail(str(name), f"unknown field; expected {', '.join(allowed)}")


def _source(data: Any, path: Path | None, index: int) -> LightSource:
    fields = _Fields(data, path, f"lights[{index}]")
    kind = fields.data.get("type")
    if kind not in FIELDS:
        raise fields.fail("type", f"expected one of {', '.join(FIELDS)}, found {kind!r}")
    required, optional = FIELDS[kind]
    fields.check_keys(("type", *required, *optional), required)
    if kind == "point":
        return PointLight(fields.vector("position"), fields.colour("intensity"), True)
    if kind == "directional":
        return DirectionalLight(fields.vector("direction", unit=True), fields.colour("irradiance"))
    if kind == "sphere":
        return SphereLight(
            fields.vector("centre"),
            fields.number("radius", positive=True),
            fields.colour("intensity"),
            fields.count("samples"),
        )
    if kind == "rect":
        u, v = fields.vector("u"), fields.vector("v")
        if not np.linalg.norm(np.cross(u, v)) > 0.0:
            raise fields.fail("v", "u and v must span a rectangle (not parallel, not zero)")
        return RectLight(
            fields.vector("centre"), u, v, fields.colour("intensity"), fields.count("samples")
        )
    source = fields.data["map"]
    if not isinstance(source, str) or not source:
        raise fields.fail(
            "map",
            f"expected a built-in map ({', '.join(BUILT_IN_MAPS)}) or an .exr/.hdr file, "
            f"found {source!r}",
        )
    return EnvironmentMap(
        source,
        fields.number("rotation", 0.0),
        fields.number("exposure", 0.0),
        fields.vector("up", unit=True) if "up" in fields.data else None,
        fields.count("samples"),
        path.parent if path is not None else None,
    )


def lighting_from_dict(data: Any, path: Path | None = None) -> Lighting:
    """A `Lighting` from parsed JSON (module docstring); a `DatasetError` naming ``path`` and the
    field."""
    fields = _Fields(data, path, "")
    fields.check_keys(("lights", "samples", "seed"), ("lights",))
    lights = fields.data["lights"]
    if not isinstance(lights, list) or not lights:
        raise fields.fail("lights", f"expected a non-empty list of lights, found {lights!r}")
    seed = fields.data.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise fields.fail("seed", f"expected a whole number ≥ 0, found {seed!r}")
    name = path.stem if path is not None else "lighting"
    return Lighting(
        tuple(_source(light, path, i) for i, light in enumerate(lights)),
        fields.count("samples", DEFAULT_SAMPLES) or DEFAULT_SAMPLES,
        seed,
        name,
    )


def read_lighting(path: str | Path) -> Lighting:
    """The lighting of a JSON file (module docstring); a `DatasetError` naming the file and the
    field."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise DatasetError(
            f"cannot read the lighting file ({error.__class__.__name__}: {error})", path=path
        ) from None
    try:
        data = parse_json(text)
    except ValueError as error:
        raise DatasetError(str(error), path=path) from None
    return lighting_from_dict(data, path)


def environment_lighting(
    source: str,
    samples: int | None = None,
    seed: int = 0,
    rotation: float = 0.0,
    exposure: float = 0.0,
) -> Lighting:
    """The lighting of one environment map (a built-in name or an .exr/.hdr file), as ``--envmap``
    gives it."""
    name = source if source in BUILT_IN_MAPS else Path(source).stem
    return Lighting(
        (EnvironmentMap(source, rotation, exposure, None, samples),),
        samples or DEFAULT_SAMPLES,
        seed,
        name,
    )


def _list(vector: np.ndarray) -> list[float]:
    return [float(v) for v in np.asarray(vector, dtype=np.float64)]


def source_to_dict(source: LightSource) -> dict[str, Any]:
    """One light as its JSON object (module docstring)."""
    if isinstance(source, PointLight):
        return {
            "type": "point",
            "position": _list(source.position),
            "intensity": _list(source.intensity),
        }
    if isinstance(source, DirectionalLight):
        return {
            "type": "directional",
            "direction": _list(source.direction),
            "irradiance": _list(source.irradiance),
        }
    count = {"samples": source.samples} if source.samples is not None else {}
    if isinstance(source, SphereLight):
        return {
            "type": "sphere",
            "centre": _list(source.centre),
            "radius": float(source.radius),
            "intensity": _list(source.intensity),
            **count,
        }
    if isinstance(source, RectLight):
        return {
            "type": "rect",
            "centre": _list(source.centre),
            "u": _list(source.u),
            "v": _list(source.v),
            "intensity": _list(source.intensity),
            **count,
        }
    up = {"up": _list(source.up)} if source.up is not None else {}
    return {
        "type": "envmap",
        "map": source.source,
        "rotation": float(source.rotation),
        "exposure": float(source.exposure),
        **up,
        **count,
    }


def lighting_to_dict(lighting: Lighting) -> dict[str, Any]:
    """The lighting as JSON data that `lighting_from_dict` reads back to the same lighting."""
    return {
        "samples": lighting.samples,
        "seed": lighting.seed,
        "lights": [source_to_dict(source) for source in lighting.sources],
    }


def write_lighting(path: str | Path, lighting: Lighting) -> Path:
    """Write the lighting as JSON, atomically (a map file is written as named: relative to its
    lighting file)."""
    return write_json(path, lighting_to_dict(lighting))


__all__ = [
    "FIELDS",
    "environment_lighting",
    "lighting_from_dict",
    "lighting_to_dict",
    "read_lighting",
    "source_to_dict",
    "write_lighting",
]
