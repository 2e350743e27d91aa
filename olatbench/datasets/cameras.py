"""Camera conventions: the one place where axes and intrinsics are converted.

olatbench stores camera-to-world matrices in **OpenCV axes** (x right, y down,
z forward) and intrinsics ``K`` in pixels with pixel centres at ``+0.5``: the
centre of the top-left pixel is ``(0.5, 0.5)`` and a camera whose principal
point is the image centre has ``cx = width / 2``.

The NeRF-style JSON files of NRHints, GS³ and SSS-GS store camera-to-world in
**OpenGL/Blender axes** (x right, y up, z backward). The two differ by a flip
of the y and z camera axes, which is its own inverse.

GS³ and SSD-GS save refined poses as ``R_opt``/``T_opt`` in the 3DGS convention: ``R`` is the
world-to-camera rotation transposed (OpenCV axes) and ``T`` the world-to-camera translation
(`c2w_from_refined`).
"""

from __future__ import annotations

import math

import numpy as np

from olatbench.datasets import portable

# diag(1, -1, -1, 1): right-multiplying a camera-to-world matrix flips its camera y and z axes.
_FLIP_YZ = np.diag([1.0, -1.0, -1.0, 1.0])


def opengl_to_opencv(c2w: np.ndarray) -> np.ndarray:
    """Camera-to-world (4×4) from OpenGL/Blender camera axes to OpenCV camera axes."""
    c2w = np.asarray(c2w, dtype=np.float64)
    if c2w.shape == (3, 4):
        c2w = np.vstack([c2w, [0.0, 0.0, 0.0, 1.0]])
    return c2w @ _FLIP_YZ


def opencv_to_opengl(c2w: np.ndarray) -> np.ndarray:
    """Camera-to-world (4×4) from OpenCV camera axes to OpenGL/Blender camera axes."""
    return opengl_to_opencv(c2w)


def c2w_from_refined(R: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Camera-to-world (4×4, OpenCV axes) of a 3DGS-style pose: world-to-camera = [[Rᵀ, T], [0, 1]]
    (GS³/SSD-GS scene/dataset_readers.py: ``R = transpose(w2c[:3, :3])``, ``T = w2c[:3, 3]``)."""
    w2c = np.eye(4)
    w2c[:3, :3] = np.asarray(R, dtype=np.float64).T
    w2c[:3, 3] = np.asarray(T, dtype=np.float64)
    return np.linalg.inv(w2c)


def intrinsics_matrix(fx: float, fy: float, cx: float, cy: float) -> np.ndarray:
    """3×3 pinhole intrinsics in pixels."""
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]], dtype=np.float64)


def focal_from_fov(fov_x: float, width: int) -> float:
    """Focal length in pixels from a horizontal field of view in radians (``camera_angle_x``)."""
    return 0.5 * width / math.tan(0.5 * fov_x)


def fov_from_focal(focal: float, width: int) -> float:
    """Horizontal field of view in radians from a focal length in pixels."""
    return 2.0 * math.atan(0.5 * width / focal)


def intrinsics_from_fov(fov_x: float, width: int, height: int) -> np.ndarray:
    """Square-pixel intrinsics with the principal point at the image centre."""
    focal = focal_from_fov(fov_x, width)
    return intrinsics_matrix(focal, focal, width / 2.0, height / 2.0)


def scale_intrinsics(K: np.ndarray, sx: float, sy: float) -> np.ndarray:
    """Intrinsics after resizing the image by ``sx`` × ``sy`` (pixel centres at +0.5 keep this
    exact)."""
    scaled = np.array(K, dtype=np.float64, copy=True)
    scaled[0, :] *= sx
    scaled[1, :] *= sy
    return scaled


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray = (0.0, 0.0, 1.0)) -> np.ndarray:
    """OpenCV camera-to-world (4×4) at ``eye`` looking at ``target``; ``up`` is world up.

    Falls back to another up vector when the view direction is parallel to ``up``.
    """
    eye = np.asarray(eye, dtype=np.float64)
    forward = np.asarray(target, dtype=np.float64) - eye
    forward /= portable.norm(forward)
    up = np.asarray(up, dtype=np.float64)
    right = np.cross(forward, up)
    if portable.norm(right) < 1e-8:
        right = np.cross(
            forward, np.array([0.0, 1.0, 0.0]) if abs(up[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
        )
    right /= portable.norm(right)
    down = np.cross(forward, right)
    c2w = np.eye(4)
    c2w[:3, 0], c2w[:3, 1], c2w[:3, 2], c2w[:3, 3] = right, down, forward, eye
    return c2w


def project_points(
    points: np.ndarray, K: np.ndarray, c2w: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Project world points (N, 3) with an OpenCV camera: pixel coordinates (N, 2) and depths
    (N,)."""
    w2c = np.linalg.inv(c2w)
    cam = np.asarray(points, dtype=np.float64) @ w2c[:3, :3].T + w2c[:3, 3]
    depth = cam[:, 2]
    uv = (cam @ np.asarray(K, dtype=np.float64).T)[:, :2] / depth[:, None]
    return uv, depth
