"""A similarity-transformed copy of a NeRF-style scene folder (NRHints, GS³), written with plain
numpy and json.

The copy has the same images; every camera pose (``transform_matrix``, camera-to-world in OpenGL
axes: the move acts on the left, so the axes convention does not matter), light position
(``pl_pos``) and near/far distance is moved by ``x -> scale · R x + t``, and light intensities
(``pl_intensity``) are × scale², so the irradiance at every moved point is the original's: the same
scene in another world frame and unit of length.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np


def rotation(axis, angle: float) -> np.ndarray:
    """Rodrigues' formula: the rotation by ``angle`` about ``axis``."""
    a = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    cross = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * cross @ cross


#: s = 10, a rotation and a translation of ~60 units (the test scenes' objects have radius ≲ 1,
#: cameras at 4).
SCALE, ROTATION, TRANSLATION = 10.0, rotation([1.0, 2.0, 3.0], 1.1), np.array([30.0, -50.0, 20.0])


def move_point(point) -> np.ndarray:
    return SCALE * ROTATION @ np.asarray(point, np.float64) + TRANSLATION


def move_scene(source: Path, target: Path) -> Path:
    """Copy the scene folder ``source`` to ``target`` with every ``transforms_*.json`` moved
    (module docstring)."""
    shutil.copytree(source, target)
    for path in Path(target).glob("transforms_*.json"):
        meta = json.loads(path.read_text())
        for key in ("camera_near", "camera_far"):
            if key in meta:
                meta[key] *= SCALE
        for frame in meta["frames"]:
            c2w = np.asarray(frame["transform_matrix"], np.float64)
            c2w[:3, :3] = ROTATION @ c2w[:3, :3]
            c2w[:3, 3] = move_point(c2w[:3, 3])
            frame["transform_matrix"] = c2w.tolist()
            frame["pl_pos"] = move_point(frame["pl_pos"]).tolist()
            if "pl_intensity" in frame:
                frame["pl_intensity"] = (
                    np.asarray(frame["pl_intensity"], np.float64) * SCALE**2
                ).tolist()
        path.write_text(json.dumps(meta, indent=1))
    return Path(target)
