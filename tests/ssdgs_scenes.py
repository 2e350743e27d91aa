"""A closed-form test scene for SSD-GS: a Lambertian sphere lit by point lights (no rendering library).

Pixel value = albedo · max(n·ωi, 0) · I / d² where a camera ray hits the unit sphere (self-shadowing
is exactly the ``max`` for a convex object), the background elsewhere.
"""

from __future__ import annotations

import numpy as np

from olatbench.datasets.cameras import intrinsics_from_fov, look_at
from olatbench.datasets.records import Camera, PointLight
from olatbench.methods.base import Views

ALBEDO = np.array([0.75, 0.5, 0.3])
LIGHT_INTENSITY = 16.0


def _directions(n: int, rng: np.random.Generator, min_elevation: float = -0.3) -> np.ndarray:
    out = []
    while len(out) < n:
        v = rng.normal(size=3)
        v /= np.linalg.norm(v)
        if v[2] > min_elevation:
            out.append(v)
    return np.array(out)


def render_sphere(camera: Camera, light: PointLight, background: float = 0.0) -> np.ndarray:
    """(H, W, 3) float32 image of the Lambertian unit sphere at the origin."""
    ys, xs = np.mgrid[0:camera.height, 0:camera.width] + 0.5
    pix = np.stack([xs, ys, np.ones_like(xs)], axis=-1) @ np.linalg.inv(camera.K).T
    dirs = pix @ camera.c2w[:3, :3].T
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    origin = camera.c2w[:3, 3]
    b = dirs @ origin
    disc = b * b - (origin @ origin - 1.0)
    hit = disc > 0
    t = -b - np.sqrt(np.where(hit, disc, 0.0))
    points = origin + t[..., None] * dirs
    to_light = light.position - points
    d2 = np.sum(to_light**2, axis=-1, keepdims=True)
    cos = np.clip(np.sum(points * to_light, axis=-1, keepdims=True) / np.sqrt(d2), 0.0, None)
    shaded = ALBEDO * cos * light.intensity / d2
    image = np.where(hit[..., None], shaded, background)
    return np.clip(image, 0.0, 1.0).astype(np.float32)


def sphere_views(n: int, size: int = 48, seed: int = 0, background: float = 0.0) -> Views:
    """``n`` views of the sphere: cameras at distance 4, lights at distance 5, random directions."""
    rng = np.random.default_rng(seed)
    K = intrinsics_from_fov(np.radians(40.0), size, size)
    cameras = [Camera(K=K, c2w=look_at(4.0 * d, np.zeros(3)), width=size, height=size)
               for d in _directions(n, rng)]
    lights = [PointLight(position=5.0 * d, intensity=np.full(3, LIGHT_INTENSITY), intensity_known=True)
              for d in _directions(n, rng, min_elevation=0.0)]
    images = np.stack([render_sphere(c, lt, background) for c, lt in zip(cameras, lights, strict=True)])
    return Views(cameras=cameras, lights=lights, images=images, frame_ids=[f"{i:03d}" for i in range(n)],
                 background=np.full(3, background, dtype=np.float32), scene_name="lambert-sphere")
