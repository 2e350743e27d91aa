"""Conversions between the browser's camera and light controls and olatbench's records (numpy only).

Conventions: olatbench cameras are OpenCV camera-to-world with pixel centres at +0.5
(`olatbench.datasets.cameras`); viser's browser camera is OpenCV too (+z forward, +y down), given as
a unit quaternion ``wxyz`` of the camera-to-world rotation, a position and a *vertical* field of
view in radians.

The light's spherical coordinates are taken about the scene centre with the scene's up axis
(`orbit_frame` of the training cameras): ``elevation`` in degrees above the plane normal to up,
``azimuth`` in degrees about up, measured from a reference direction ``forward`` in that plane (the
first training camera's direction from the centre, projected), counter-clockwise seen from above;
``distance`` in scene units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from olatbench.datasets.records import Camera

# default cap of a render's longer side in pixels (a wide window: 512×263, about 0.1 s on a CPU)
MAX_RESOLUTION = 512


def quaternion_to_matrix(wxyz: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of a quaternion (w, x, y, z) (normalised first)."""
    w, x, y, z = np.asarray(wxyz, dtype=np.float64) / np.linalg.norm(wxyz)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def matrix_to_quaternion(rotation: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z), w ≥ 0, of a rotation matrix (3, 3) (Shepperd's method)."""
    m = np.asarray(rotation, dtype=np.float64)
    trace = np.trace(m)
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = np.array(
            [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
        )
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = np.empty(4)
        q[0] = (m[k, j] - m[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (m[j, i] + m[i, j]) / s
        q[1 + k] = (m[k, i] + m[i, k]) / s
    q /= np.linalg.norm(q)
    return -q if q[0] < 0 else q


def browser_camera(
    wxyz: np.ndarray, position: np.ndarray, fov_y: float, width: int, height: int
) -> Camera:
    """The olatbench `Camera` of a browser view rendered at ``width`` × ``height`` pixels (square
    pixels, principal point at the image centre, vertical field of view ``fov_y`` radians)."""
    focal = 0.5 * height / np.tan(0.5 * fov_y)
    K = np.array([[focal, 0.0, 0.5 * width], [0.0, focal, 0.5 * height], [0.0, 0.0, 1.0]])
    c2w = np.eye(4)
    c2w[:3, :3] = quaternion_to_matrix(wxyz)
    c2w[:3, 3] = position
    return Camera(K=K, c2w=c2w, width=int(width), height=int(height))


def camera_pose(camera: Camera) -> tuple[np.ndarray, np.ndarray, float]:
    """(wxyz, position, vertical fov in radians) of a camera, for the browser (the inverse of
    `browser_camera` up to the principal point and aspect, which the browser's canvas decides)."""
    return (
        matrix_to_quaternion(camera.c2w[:3, :3]),
        camera.c2w[:3, 3].copy(),
        float(2.0 * np.arctan(0.5 * camera.height / camera.fy)),
    )


def render_size(canvas: tuple[int, int], max_side: int, scale: float = 1.0) -> tuple[int, int]:
    """(width, height) of a render for a browser canvas of ``canvas`` = (width, height) pixels: the
    canvas's size, shrunk with its aspect so that the longer side is at most ``max_side``, times
    ``scale``; at least 8 pixels."""
    width, height = canvas
    factor = min(1.0, max_side / max(width, height)) * scale
    return max(8, round(width * factor)), max(8, round(height * factor))


@dataclass(frozen=True)
class LightFrame:
    """The frame the light sliders use: ``centre`` (3,), unit ``up`` (3,) and unit ``forward`` (3,)
    ⟂ up."""

    centre: np.ndarray
    up: np.ndarray
    forward: np.ndarray

    @classmethod
    def of(cls, centre: np.ndarray, up: np.ndarray, reference: np.ndarray) -> LightFrame:
        """The frame with ``forward`` = ``reference - centre`` made perpendicular to ``up`` (any
        perpendicular when they are parallel)."""
        up = np.asarray(up, dtype=np.float64) / np.linalg.norm(up)
        forward = np.asarray(reference, dtype=np.float64) - centre
        forward = forward - (forward @ up) * up
        if np.linalg.norm(forward) < 1e-9:
            forward = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
        return cls(np.asarray(centre, dtype=np.float64), up, forward / np.linalg.norm(forward))

    @property
    def left(self) -> np.ndarray:
        """``up × forward``: azimuth +90°."""
        return np.cross(self.up, self.forward)

    def spherical(self, position: np.ndarray) -> tuple[float, float, float]:
        """(azimuth °, elevation °, distance) of a world position."""
        offset = np.asarray(position, dtype=np.float64) - self.centre
        distance = float(np.linalg.norm(offset))
        if distance == 0.0:
            return 0.0, 0.0, 0.0
        elevation = float(np.degrees(np.arcsin(np.clip(offset @ self.up / distance, -1.0, 1.0))))
        azimuth = float(np.degrees(np.arctan2(offset @ self.left, offset @ self.forward)))
        return azimuth, elevation, distance

    def position(self, azimuth: float, elevation: float, distance: float) -> np.ndarray:
        """World position (3,) of spherical coordinates (degrees, scene units)."""
        a, e = np.radians(azimuth), np.radians(elevation)
        direction = (
            np.cos(e) * (np.cos(a) * self.forward + np.sin(a) * self.left) + np.sin(e) * self.up
        )
        return self.centre + distance * direction
