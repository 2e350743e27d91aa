"""A lighting: a list of light sources, and the point and distant lights that stand for it.

Sources (world units and frame of the scene, as `olatbench.datasets.records`):

* `olatbench.datasets.records.PointLight`: ``position`` (3,), RGB radiant ``intensity`` (3,),
  inverse-square;
* `DirectionalLight`: ``direction`` (3,) unit vector from the scene towards the light, RGB
  ``irradiance`` (3,) on a surface facing it (a point light of intensity ``E d²`` at distance ``d``
  along it, as ``d`` → ∞);
* `SphereLight`, `RectLight`: area lights, sampled into ``samples`` isotropic point lights spread
  over the sphere's surface or the rectangle (stratified, seeded), each with
  ``intensity / samples``: from far away each acts as one point light of ``intensity`` at its
  centre;
* `EnvironmentMap`: an equirectangular map (`olatbench.datasets.lighting.envmap`: a built-in name or
  an .exr/.hdr file), importance-sampled into ``samples`` directional lights.

`Lighting.sample` turns the whole list into `SampledLights` (point lights and directional lights)
that a renderer sums; the same lighting, sample counts and seed give the same lights on every
machine.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from olatbench.datasets.lighting.envmap import load_map, sample_map
from olatbench.datasets.records import PointLight

DEFAULT_SAMPLES = 64
GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0


@dataclass(frozen=True, eq=False)
class DirectionalLight:
    """A light at infinity: unit ``direction`` (3,) towards it, RGB ``irradiance`` (3,) on a surface
    facing it."""

    direction: np.ndarray
    irradiance: np.ndarray


@dataclass(frozen=True, eq=False)
class SphereLight:
    """A spherical area light: ``centre`` (3,), ``radius``, total RGB radiant ``intensity`` (3,),
    point ``samples`` (None: the lighting's default)."""

    centre: np.ndarray
    radius: float
    intensity: np.ndarray
    samples: int | None = None


@dataclass(frozen=True, eq=False)
class RectLight:
    """A rectangular area light: ``centre`` (3,), full edge vectors ``u`` and ``v`` (3,), total RGB
    radiant ``intensity`` (3,), point ``samples`` (None: the lighting's default)."""

    centre: np.ndarray
    u: np.ndarray
    v: np.ndarray
    intensity: np.ndarray
    samples: int | None = None


@dataclass(frozen=True, eq=False)
class EnvironmentMap:
    """An equirectangular environment map: ``source`` a built-in name or a file
    (relative to ``base``), turned by ``rotation`` degrees about ``up`` (None: the scene's vertical,
    given to `Lighting.sample`), scaled by 2**``exposure``, sampled into ``samples`` directional
    lights (None: the lighting's default)."""

    source: str
    rotation: float = 0.0
    exposure: float = 0.0
    up: np.ndarray | None = None
    samples: int | None = None
    base: Path | None = None

    def radiance(self) -> np.ndarray:
        """The map's radiance (H, W, 3) before rotation and exposure
        (`olatbench.datasets.lighting.envmap`)."""
        return load_map(self.source, self.base)


LightSource = PointLight | DirectionalLight | SphereLight | RectLight | EnvironmentMap


@dataclass(frozen=True)
class SampledLights:
    """The point and directional lights that stand for a lighting; a renderer sums its image under
    each."""

    points: tuple[PointLight, ...] = ()
    directions: tuple[DirectionalLight, ...] = ()

    def __len__(self) -> int:
        return len(self.points) + len(self.directions)


@dataclass(frozen=True)
class Lighting:
    """A list of light sources; ``samples`` is the default sample count of the area lights and
    environment maps that do not give theirs, ``seed`` seeds their stratified sampling."""

    sources: tuple[LightSource, ...]
    samples: int = DEFAULT_SAMPLES
    seed: int = 0
    name: str = field(default="lighting", compare=False)

    def sample(self, up: np.ndarray | None = None, samples: int | None = None) -> SampledLights:
        """The point and directional lights of every source; ``up`` (3,) is the vertical of the maps
        that give none (default +z), ``samples`` overrides every area light's and map's count."""
        rng = np.random.default_rng(self.seed)
        points: list[PointLight] = []
        directions: list[DirectionalLight] = []
        for source in self.sources:
            count = samples or getattr(source, "samples", None) or self.samples
            if isinstance(source, PointLight):
                points.append(source)
            elif isinstance(source, DirectionalLight):
                directions.append(source)
            elif isinstance(source, SphereLight | RectLight):
                points += area_points(source, count, rng)
            else:
                vertical = (
                    source.up
                    if source.up is not None
                    else up
                    if up is not None
                    else np.array([0.0, 0, 1])
                )
                dirs, irradiance = sample_map(
                    source.radiance(), count, rng, vertical, source.rotation, source.exposure
                )
                directions += [
                    DirectionalLight(d, e) for d, e in zip(dirs, irradiance, strict=True)
                ]
        return SampledLights(tuple(points), tuple(directions))


def stratified_square(count: int, rng: np.random.Generator) -> np.ndarray:
    """(count, 2) points in [0, 1)²: one in each of ``count`` rows, at golden-ratio offsets across
    them, both jittered (a jittered Fibonacci lattice: evenly spread for any count)."""
    rows = (np.arange(count) + rng.random(count)) / count
    cols = (np.arange(count) * GOLDEN + rng.random() + rng.random(count) / count) % 1.0
    return np.stack([rows, cols], axis=-1)


def area_points(
    light: SphereLight | RectLight, count: int, rng: np.random.Generator
) -> list[PointLight]:
    """``count`` isotropic point lights of ``intensity / count`` spread over an area light
    (module docstring)."""
    if count < 1:
        raise ValueError(f"an area light needs at least 1 sample, not {count}")
    square = stratified_square(count, rng)
    if isinstance(light, SphereLight):
        z = 1.0 - 2.0 * square[:, 0]  # uniform in z is uniform in area on the sphere
        phi = 2.0 * np.pi * square[:, 1]
        r = np.sqrt(np.clip(1.0 - z * z, 0.0, None))
        offsets = light.radius * np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)
    else:
        offsets = (square[:, :1] - 0.5) * light.u + (square[:, 1:] - 0.5) * light.v
    share = np.asarray(light.intensity, dtype=np.float64) / count
    return [
        PointLight(np.asarray(light.centre, dtype=np.float64) + offset, share.copy(), True)
        for offset in offsets
    ]


__all__ = [
    "DEFAULT_SAMPLES",
    "DirectionalLight",
    "EnvironmentMap",
    "LightSource",
    "Lighting",
    "RectLight",
    "SampledLights",
    "SphereLight",
    "area_points",
    "stratified_square",
]
