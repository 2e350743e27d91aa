"""Where methods place their initial random Gaussians."""

from __future__ import annotations

import numpy as np

from olatbench.methods.base import Views


def initial_ball(views: Views, radius: float | None) -> tuple[np.ndarray, float]:
    """Centre (3,) and radius of the ball holding the initial random Gaussians, in world units.

    With ``radius`` given: the origin and that radius (1.0: the SSD-GS paper's "unit sphere"; the official code's
    box [-0.5, 0.5]³ is the cube of half-side radius / 2 around the centre, ``init_shape="box"``).
    With ``None``: the point closest, in least squares, to all cameras' optical axes, and 0.55 × the median
    camera distance to it (for scenes whose object is not at the origin).
    """
    if radius is not None:
        return np.zeros(3), float(radius)
    origins = np.stack([c.position for c in views.cameras])
    axes = np.stack([c.c2w[:3, 2] / np.linalg.norm(c.c2w[:3, 2]) for c in views.cameras])
    projector = np.eye(3)[None] - axes[:, :, None] * axes[:, None, :]  # (N, 3, 3) I - d dᵀ
    centre = np.linalg.lstsq(projector.sum(0), (projector @ origins[:, :, None]).sum(0)[:, 0], rcond=None)[0]
    return centre, 0.55 * float(np.median(np.linalg.norm(origins - centre, axis=1)))

