"""Equirectangular environment maps: the built-in procedural ones, HDR files, and importance
sampling into distant lights.

Conventions (one implementation, used by every verb):

* A map is float64 (H, W, 3) **linear radiance** (the unit of the scene's irradiance per steradian),
  usually W = 2H.
* Row ``i`` covers polar angles θ ∈ [π i / H, π (i + 1) / H) measured from the map's **up** axis
  (row 0 is the zenith); column ``j`` covers azimuths φ ∈ [2π j / W, 2π (j + 1) / W) measured
  counter-clockwise about up from the map's **x** axis (`map_axes`: the world +x projected off up,
  or +y when up is along x).
* ``rotation`` (degrees) turns the map about its up axis (a direction at azimuth φ in the map is
  seen at φ + rotation); ``exposure`` (stops) scales the radiance by 2**exposure.

`sample_map` turns a map into ``count`` directional lights by stratified importance sampling of the
piecewise-constant map: the probability of a pixel is ∝ its luminance (Rec. 709 weights) × its solid
angle, ``count`` stratified uniforms pick pixels through the inverse CDF, and a direction is drawn
uniformly in the pixel's solid angle, so its density per steradian is ``p = P_pixel / Ω_pixel``.
Each light's irradiance (on a surface facing it) is ``L(ω) / (p(ω) · count)``: the sum over the
lights of ``f(ω_k) E_k`` is an unbiased estimate of ``∫ L(ω) f(ω) dω`` for any shading ``f``, whose
error falls at least as ``count^-1/2``.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from olatbench.datasets.errors import DatasetError

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 / sRGB primaries
MAP_HEIGHT = 256  # the built-in maps' rows (W = 2H: 0.7° pixels)
MAP_SUFFIXES = (".exr", ".hdr")


def map_axes(up: np.ndarray) -> np.ndarray:
    """(3, 3) rows x, y, up of a map's frame in world coordinates for a world ``up`` (3,)
    (normalised here)."""
    up = np.asarray(up, dtype=np.float64)
    norm = np.linalg.norm(up)
    if not (np.all(np.isfinite(up)) and norm > 0.0):
        raise ValueError(f"up must be a non-zero vector, not {up.tolist()}")
    up = up / norm
    seed = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = seed - (seed @ up) * up
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(up, x), up])


def pixel_directions(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """(θ (H, 1) polar angle from up, φ (1, W) azimuth) of the pixel centres of an (H, W) map, in
    radians."""
    theta = (np.arange(height)[:, None] + 0.5) * np.pi / height
    phi = (np.arange(width)[None, :] + 0.5) * 2.0 * np.pi / width
    return theta, phi


def pixel_solid_angles(height: int, width: int) -> np.ndarray:
    """(H, 1) solid angle of each pixel of a row (steradians; they sum to 4π over the map)."""
    edges = np.cos(np.arange(height + 1) * np.pi / height)
    return ((edges[:-1] - edges[1:]) * 2.0 * np.pi / width)[:, None]


def _smoothstep(edge0: float, edge1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - edge0) / (edge1 - edge0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _local_directions(height: int) -> np.ndarray:
    """(H, 2H, 3) unit directions of a built-in map's pixel centres in the map's frame
    (x, y, up)."""
    theta, phi = pixel_directions(height, 2 * height)
    return np.stack(
        np.broadcast_arrays(
            np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)
        ),
        axis=-1,
    )


def furnace(height: int = 32) -> np.ndarray:
    """A white furnace: radiance 1 from every direction (irradiance π on any surface)."""
    return np.ones((height, 2 * height, 3))


def studio(height: int = MAP_HEIGHT) -> np.ndarray:
    """A photo studio: a dim grey room (0.03), a dark floor, and three soft boxes, a warm key
    (radiance 12, front left, 40° up, ≈ 30° × 20°), a cool fill (4, front right, 15° up) and a white
    rim light (8, behind, 55° up), each with soft (smoothstep) edges."""
    d = _local_directions(height)
    radiance = np.full(d.shape, 0.03)
    radiance[d[..., 2] < 0.0] = 0.015
    boxes = (
        (40.0, 135.0, 0.55, 0.35, (12.0, 11.0, 9.5)),
        (15.0, 225.0, 0.45, 0.30, (3.4, 3.8, 4.4)),
        (55.0, 0.0, 0.30, 0.25, (8.0, 8.0, 8.0)),
    )
    for elevation, azimuth, half_width, half_height, colour in boxes:
        centre = _direction(elevation, azimuth)
        right = np.cross([0.0, 0.0, 1.0], centre)
        right /= np.linalg.norm(right)
        top = np.cross(centre, right)
        facing = d @ centre
        plane = d / np.maximum(facing, 1e-6)[..., None]  # onto the box's plane at distance 1
        across, upward = np.abs(plane @ right), np.abs(plane @ top)
        weight = (
            (facing > 0.0)
            * (1.0 - _smoothstep(0.8 * half_width, half_width, across))
            * (1.0 - _smoothstep(0.8 * half_height, half_height, upward))
        )
        radiance += weight[..., None] * np.asarray(colour)
    return radiance


def sky(height: int = MAP_HEIGHT) -> np.ndarray:
    """A clear sky with the sun: blue at the zenith (0.25, 0.45, 0.9) fading to a pale horizon
    (0.8, 0.85, 0.9), a brown ground (0.12, 0.1, 0.08) below, and a sun disc 30° up at azimuth 60°
    (radius 2°, radiance 2000 × (1, 0.95, 0.85) with a soft edge: an irradiance of ≈ (6.2, 5.9, 5.2)
    facing the sun, against the sky's ≈ (1.1, 1.7, 2.8) on a level surface)."""
    d = _local_directions(height)
    elevation = d[..., 2:3]
    horizon, zenith = np.array([0.8, 0.85, 0.9]), np.array([0.25, 0.45, 0.9])
    blend = np.sqrt(np.clip(elevation, 0.0, 1.0))
    radiance = np.where(
        elevation >= 0.0, horizon + blend * (zenith - horizon), np.array([0.12, 0.1, 0.08])
    )
    angle = np.degrees(np.arccos(np.clip(d @ _direction(30.0, 60.0), -1.0, 1.0)))
    disc = 1.0 - _smoothstep(1.6, 2.0, angle)
    return radiance + disc[..., None] * 2000.0 * np.array([1.0, 0.95, 0.85])


def _direction(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    """The unit direction (3,) at an elevation above the map's horizon and an azimuth from its x
    axis."""
    e, a = np.radians(elevation_deg), np.radians(azimuth_deg)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


BUILT_IN_MAPS: dict[str, Callable[[], np.ndarray]] = {
    "studio": studio,
    "sky": sky,
    "furnace": furnace,
}


def load_map(source: str, base: Path | None = None) -> np.ndarray:
    """The radiance (H, W, 3) float64 of a built-in map's name (`BUILT_IN_MAPS`) or an
    ``.exr``/``.hdr`` file (read through OpenImageIO; relative to ``base``, the folder of the
    lighting file, when given); a `DatasetError` naming the file otherwise."""
    if source in BUILT_IN_MAPS:
        return BUILT_IN_MAPS[source]()
    from olatbench.datasets.images import read_image

    path = Path(source) if base is None or Path(source).is_absolute() else base / source
    if path.suffix.lower() not in MAP_SUFFIXES:
        raise DatasetError(
            f"an environment map is one of {', '.join(BUILT_IN_MAPS)} or an .exr/.hdr file, "
            f"not {source!r}",
            path=path if path.exists() else None,
        )
    pixels = read_image(path)  # a DatasetError naming the file when missing or unreadable
    if pixels.ndim != 3 or pixels.shape[2] < 3:
        raise DatasetError(
            f"an environment map needs 3 colour channels, found {pixels.shape[-1]}", path=path
        )
    radiance = pixels[..., :3].astype(np.float64)
    if not np.all(np.isfinite(radiance)) or radiance.min() < 0.0:
        raise DatasetError("environment map holds negative, NaN or Inf radiance", path=path)
    if abs(radiance.shape[1] - 2 * radiance.shape[0]) > 1:
        raise DatasetError(
            f"an equirectangular map is twice as wide as high; this one is {radiance.shape[1]}×"
            f"{radiance.shape[0]}",
            path=path,
        )
    return radiance


def sample_map(
    radiance: np.ndarray,
    count: int,
    rng: np.random.Generator,
    up: np.ndarray,
    rotation_deg: float = 0.0,
    exposure: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """(directions (count, 3) unit world vectors towards the light, irradiances (count, 3)) of
    ``count`` distant lights importance-sampled from ``radiance`` (module docstring); a `ValueError`
    for a black map or ``count`` < 1."""
    if count < 1:
        raise ValueError(f"the number of environment samples must be at least 1, not {count}")
    height, width = radiance.shape[:2]
    radiance = np.asarray(radiance, dtype=np.float64) * 2.0**exposure
    omega = np.broadcast_to(pixel_solid_angles(height, width), (height, width))
    mass = (np.clip(radiance @ LUMINANCE, 0.0, None) * omega).reshape(-1)
    total = mass.sum()
    if not total > 0.0:
        raise ValueError("the environment map is black: nothing to sample")
    cdf = np.cumsum(mass) / total
    strata = (np.arange(count) + rng.random(count)) / count
    index = np.minimum(np.searchsorted(cdf, strata, side="right"), mass.size - 1)
    # a rounding at a zero-mass pixel's edge
    index = np.where(mass[index] > 0.0, index, np.argmax(mass))
    rows, cols = np.divmod(index, width)
    phi = (cols + rng.random(count)) * 2.0 * np.pi / width + np.radians(rotation_deg)
    top, bottom = np.cos(rows * np.pi / height), np.cos((rows + 1) * np.pi / height)
    cos_theta = top - rng.random(count) * (top - bottom)
    sin_theta = np.sqrt(np.clip(1.0 - cos_theta**2, 0.0, None))
    local = np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta], axis=-1)
    directions = local @ map_axes(up)
    density = mass[index] / total / omega.reshape(-1)[index]  # per steradian
    irradiance = radiance.reshape(-1, 3)[index] / (density * count)[:, None]
    return directions, irradiance


__all__ = [
    "BUILT_IN_MAPS",
    "LUMINANCE",
    "furnace",
    "load_map",
    "map_axes",
    "pixel_directions",
    "pixel_solid_angles",
    "sample_map",
    "sky",
    "studio",
]
