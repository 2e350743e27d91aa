"""The point cloud a job's Gaussians start from: a scene folder's ``points3d.ply`` (where the
official 3DGS, GS³ and SSD-GS loaders look for one) or a file given with ``run --init-points``, for
methods with the ``init_points`` capability (`olatbench.methods.spec.CAPABILITIES`).

The plan records the file (``Job.init_points``) and its content digest (``Job.init_points_digest``,
part of the job id); the runner reads it in the dataset's world units and hands it to the method as
``Views.points``, which `Views.in_frame` moves into the method's canonical frame with the cameras
and lights (`olatbench.datasets.similarity`, the one place a frame is applied). Only positions are
used: every Gaussian starts on a point, scaled by its nearest neighbours
(`GaussianModel.from_points`); the file's colours are not (the methods learn their own albedo / SH
from the images).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from olatbench.bench.jobs import file_digest

#: The file a scene folder may hold to initialise from (the name the official loaders read).
SCENE_POINTS_FILE = "points3d.ply"


class InitPointsError(ValueError):
    """A point cloud that cannot be used; the message names the file."""


def init_points_file(scene_path: str | Path | None, given: str | Path | None = None) -> Path | None:
    """The point cloud to start from: ``given`` (``--init-points``), else the scene folder's
    ``points3d.ply`` when it has one, else None."""
    if given is not None:
        path = Path(given)
        if not path.is_file():
            raise InitPointsError(f"{path}: --init-points file not found")
        return path.resolve()
    if scene_path is not None and (Path(scene_path) / SCENE_POINTS_FILE).is_file():
        return (Path(scene_path) / SCENE_POINTS_FILE).resolve()
    return None


def points_digest(path: str | Path) -> str:
    """The content digest recorded in the job (`olatbench.bench.jobs.file_digest`)."""
    return file_digest(Path(path))


def load_init_points(path: str | Path, digest: str | None) -> np.ndarray:
    """The points (P, 3) float64 of ``path`` in the dataset's world frame; an `InitPointsError` when
    the file cannot be read, holds no point, or no longer has the content ``digest`` the job was
    planned with."""
    # the Gaussian package imports torch: plans do not
    from olatbench.gaussians.ply import PlyError, read_ply_points

    path = Path(path)
    try:
        if digest is not None and points_digest(path) != digest:
            raise InitPointsError(
                f"{path}: the point cloud changed since the job was planned (its content is part "
                "of the job id); plan the run again"
            )
        points, _colours = read_ply_points(path)
    except (OSError, PlyError) as error:
        raise InitPointsError(f"cannot read the initial points: {error}") from None
    if len(points) == 0 or not np.all(np.isfinite(points)):
        raise InitPointsError(f"{path}: the point cloud is empty or has non-finite coordinates")
    return np.asarray(points, dtype=np.float64).reshape(-1, 3)


__all__ = [
    "SCENE_POINTS_FILE",
    "InitPointsError",
    "init_points_file",
    "load_init_points",
    "points_digest",
]
