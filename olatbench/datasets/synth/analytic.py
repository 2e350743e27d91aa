"""A closed-form OLAT scene: a Lambertian unit sphere at the origin lit by point lights
(numpy only, no renderer).

Pixel value = albedo · max(n·ωi, 0) · I / d² where a camera ray hits the sphere (self-shadowing is
exactly the ``max`` for a convex object), the background elsewhere. Tests use it as an exact
reference; the paper-scale benchmarks use it where Mitsuba is not installed (a GPU node), since a
training step's cost does not depend on what the images show.
"""

from __future__ import annotations

import numpy as np

from olatbench.datasets.cameras import intrinsics_from_fov, look_at
from olatbench.datasets.records import Camera, PointLight

ALBEDO = np.array([0.75, 0.5, 0.3])
LIGHT_INTENSITY = 16.0
CAMERA_DISTANCE = 4.0
LIGHT_DISTANCE = 5.0


def unit_directions(n: int, rng: np.random.Generator, min_elevation: float = -0.3) -> np.ndarray:
    """(n, 3) random unit vectors with z > ``min_elevation`` (rejection sampling from the isotropic
    normal)."""
    out = []
    while len(out) < n:
        v = rng.normal(size=3)
        v /= np.linalg.norm(v)
        if v[2] > min_elevation:
            out.append(v)
    return np.array(out)


def sphere_hits(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """(points (H, W, 3), hit (H, W) bool) where each pixel's ray (through its centre) first meets
    the unit sphere at the origin; points are world positions, equal to the unit outward normals
    there (meaningless where not hit)."""
    ys, xs = np.mgrid[0 : camera.height, 0 : camera.width] + 0.5
    pix = np.stack([xs, ys, np.ones_like(xs)], axis=-1) @ np.linalg.inv(camera.K).T
    dirs = pix @ camera.c2w[:3, :3].T
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    origin = camera.c2w[:3, 3]
    b = dirs @ origin
    disc = b * b - (origin @ origin - 1.0)
    hit = disc > 0
    t = -b - np.sqrt(np.where(hit, disc, 0.0))
    return origin + t[..., None] * dirs, hit


def render_sphere(camera: Camera, light: PointLight, background: float = 0.0) -> np.ndarray:
    """(H, W, 3) float32 linear image of the Lambertian unit sphere at the origin, clipped to
    [0, 1]."""
    points, hit = sphere_hits(camera)
    to_light = light.position - points
    d2 = np.sum(to_light**2, axis=-1, keepdims=True)
    cos = np.clip(np.sum(points * to_light, axis=-1, keepdims=True) / np.sqrt(d2), 0.0, None)
    shaded = ALBEDO * cos * light.intensity / d2
    image = np.where(hit[..., None], shaded, background)
    return np.clip(image, 0.0, 1.0).astype(np.float32)


def sphere_rig(n: int, size: int, seed: int = 0) -> tuple[list[Camera], list[PointLight]]:
    """``n`` cameras at distance 4 looking at the origin (40° field of view, ``size``² pixels) and
    ``n`` lights at distance 5 above the horizon, both in random directions drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    K = intrinsics_from_fov(np.radians(40.0), size, size)
    cameras = [
        Camera(K=K, c2w=look_at(CAMERA_DISTANCE * d, np.zeros(3)), width=size, height=size)
        for d in unit_directions(n, rng)
    ]
    lights = [
        PointLight(
            position=LIGHT_DISTANCE * d, intensity=np.full(3, LIGHT_INTENSITY), intensity_known=True
        )
        for d in unit_directions(n, rng, min_elevation=0.0)
    ]
    return cameras, lights


__all__ = [
    "ALBEDO",
    "LIGHT_INTENSITY",
    "render_sphere",
    "sphere_hits",
    "sphere_rig",
    "unit_directions",
]
