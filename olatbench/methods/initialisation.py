"""Where methods place their initial random Gaussians."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from olatbench.datasets.records import Camera
from olatbench.datasets.similarity import rig_centre
from olatbench.gaussians.model import points_in_ball


def initial_ball(cameras: Sequence[Camera], radius: float | None) -> tuple[np.ndarray, float]:
    """Centre (3,) and radius of the ball holding the initial random Gaussians, in world units.

    With ``radius`` given: the origin and that radius (1.0: the SSD-GS paper's "unit sphere"; the
    official code's box [-0.5, 0.5]³ is the cube of half-side radius / 2 around the centre,
    ``init_shape="box"``). With ``None``: the scene's centre (`rig_centre`: for cameras looking at
    an object, the point closest, in least squares, to all their optical axes; for a forward-facing
    rig, the middle of its near/far range ahead of it), and 0.55 × the median camera distance to it
    (for scenes whose object is not at the origin).
    """
    if radius is not None:
        return np.zeros(3), float(radius)
    centre = rig_centre(cameras)
    origins = np.stack([c.position for c in cameras])
    return centre, 0.55 * float(np.median(np.linalg.norm(origins - centre, axis=1)))


def initial_points(cameras: Sequence[Camera], n: int, seed: int) -> np.ndarray:
    """(n, 3) float32 world points uniform in the ball `initial_ball` fits to ``cameras``, drawn
    from ``seed``: the centres a native method with ``init_radius=None`` (the mini presets) starts
    from with that seed."""
    centre, radius = initial_ball(cameras, None)
    return points_in_ball(n, radius, seed, tuple(centre.tolist())).cpu().numpy()
