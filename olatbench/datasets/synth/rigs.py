"""Camera and light placement: evenly spread points on spherical bands, paired at random.

Positions come from a Fibonacci lattice restricted to an elevation band (area-uniform, no clumps),
rotated about z by a seeded random angle. Lights for train and test are one lattice, interleaved
so that every test light lies between training lights (novel, never repeated).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from olatbench.datasets import portable
from olatbench.datasets.cameras import intrinsics_from_fov, look_at
from olatbench.datasets.records import Camera, PointLight
from olatbench.datasets.synth.recipe import Recipe


def band_directions(
    count: int, elevation_deg: tuple[float, float], rng: np.random.Generator
) -> np.ndarray:
    """``count`` unit vectors (count, 3) spread evenly over the band of elevations
    (degrees above z = 0)."""
    low, high = (math.radians(e) for e in elevation_deg)
    if not -math.pi / 2 <= low <= high <= math.pi / 2:
        raise ValueError(
            f"elevation range {elevation_deg} must be increasing and within [-90, 90] degrees"
        )
    golden = math.pi * (3.0 - math.sqrt(5.0))
    index = np.arange(count) + 0.5
    # area-uniform in z
    z = math.sin(low) + (math.sin(high) - math.sin(low)) * index / max(count, 1)
    azimuth = golden * index + rng.uniform(0.0, 2.0 * math.pi)
    ring = np.sqrt(np.clip(1.0 - z**2, 0.0, None))
    return np.stack([ring * portable.cos(azimuth), ring * portable.sin(azimuth), z], axis=1)


def field_of_view(recipe: Recipe) -> float:
    """Horizontal field of view (radians) at which the unit bounding sphere spans ``fill`` of the
    width."""
    half_angle = math.asin(1.0 / recipe.cameras.radius)
    return 2.0 * math.atan(math.tan(half_angle) / recipe.cameras.fill)


def make_camera(position: np.ndarray, target: np.ndarray, recipe: Recipe) -> Camera:
    """An OpenCV camera at ``position`` looking at ``target``, world z up."""
    width, height = recipe.resolution
    K = intrinsics_from_fov(field_of_view(recipe), width, height)
    return Camera(
        K=K,
        c2w=look_at(position, target, up=(0.0, 0.0, 1.0)),
        width=width,
        height=height,
        near=recipe.cameras.near,
        far=recipe.cameras.far,
    )


@dataclass(frozen=True)
class Rig:
    """Cameras and lights of every frame: ``{"train": [(Camera, PointLight), ...], "test":
    [...]}``."""

    frames: dict[str, list[tuple[Camera, PointLight]]]


def make_rig(recipe: Recipe, centre: np.ndarray) -> Rig:
    """Place the cameras and lights of ``recipe`` around ``centre`` (3,), the object's
    bounding-sphere centre (radius 1); deterministic in ``recipe.seed``."""
    centre = np.asarray(centre, dtype=np.float64)
    rng = np.random.default_rng(recipe.seed)
    n_train, n_test = recipe.train, recipe.test
    train_cameras = centre + recipe.cameras.radius * band_directions(
        n_train, recipe.cameras.elevation_deg, rng
    )
    lights = centre + recipe.lights.radius * band_directions(
        n_train + n_test, recipe.lights.elevation_deg, rng
    )
    is_test = np.zeros(n_train + n_test, dtype=bool)
    if n_test:
        is_test[np.linspace(0, n_train + n_test - 1, n_test + 2)[1:-1].round().astype(int)] = True
    train_lights, test_lights = lights[~is_test], lights[is_test]
    train_lights = train_lights[rng.permutation(n_train)]
    test_lights = test_lights[rng.permutation(n_test)]
    if recipe.novel_views:
        test_cameras = centre + recipe.cameras.radius * band_directions(
            n_test, recipe.cameras.elevation_deg, rng
        )
    else:
        test_cameras = train_cameras[rng.choice(n_train, size=n_test, replace=n_test > n_train)]
    all_cameras = np.concatenate([train_cameras, test_cameras])
    closest = np.min(portable.norm(all_cameras[:, None] - lights[None]))
    if closest <= recipe.cameras.near:
        raise ValueError(
            f"recipe '{recipe.name}': a light is {closest:.3f} from a camera, inside its near "
            f"plane ({recipe.cameras.near}); separate the camera and light radii"
        )
    intensity = np.asarray(recipe.lights.intensity, dtype=np.float64)

    def frames(cameras: np.ndarray, light_positions: np.ndarray) -> list[tuple[Camera, PointLight]]:
        return [
            (
                make_camera(c, centre, recipe),
                PointLight(position=p, intensity=intensity.copy(), intensity_known=True),
            )
            for c, p in zip(cameras, light_positions, strict=True)
        ]

    return Rig(
        frames={
            "train": frames(train_cameras, train_lights),
            "test": frames(test_cameras, test_lights),
        }
    )
