"""The closed-form Lambertian sphere (`olatbench.datasets.synth.analytic`) as training views for
SSD-GS tests."""

from __future__ import annotations

import numpy as np

from olatbench.datasets.synth.analytic import render_sphere, sphere_rig
from olatbench.methods.base import Views


def sphere_views(n: int, size: int = 48, seed: int = 0, background: float = 0.0) -> Views:
    """``n`` views of the sphere: cameras at distance 4, lights at distance 5, random directions."""
    cameras, lights = sphere_rig(n, size, seed)
    images = np.stack(
        [render_sphere(c, lt, background) for c, lt in zip(cameras, lights, strict=True)]
    )
    return Views(
        cameras=cameras,
        lights=lights,
        images=images,
        frame_ids=[f"{i:03d}" for i in range(n)],
        background=np.full(3, background, dtype=np.float32),
        scene_name="lambert-sphere",
    )
