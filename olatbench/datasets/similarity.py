"""Similarity transforms of a scene's world frame, and the canonical frame fitted to a scene's
cameras.

A `Similarity` maps a point ``x`` to ``scale · R x + t`` (``R`` a proper rotation). It moves every
record of a scene consistently: camera poses (``K`` and the image size do not change), near/far
distances (× scale), light positions, and light intensities × scale² so that the inverse-square
irradiance ``I / d²`` at every transformed point is unchanged; Gaussians (centres, log-scales +
log(scale), wxyz quaternions rotated by ``R``).

`canonical_frame` is the one world -> canonical transform olatbench uses (docs/architecture.md, "The
canonical frame"): it depends on the cameras only and is equivariant, so a scene and any
similarity-transformed copy of it (same images) have the same canonical cameras and lights to
rounding. In the canonical frame:

* the origin is the scene's centre (`rig_centre`): for a rig whose optical axes converge in front of
  the cameras (object-centric: a turntable, a light stage, a hand-held orbit) the point nearest, in
  least squares, to every axis (`axes_centre`); for a forward-facing rig (axes nearly parallel, as
  in phone or LLFF captures, where that point is not pinned down) the point at the middle of the
  cameras' depth range (``camera_near``/``camera_far``) ahead of their mean position along their
  mean viewing direction, as LLFF fits its bounds;
* the median camera distance to it is `CANONICAL_CAMERA_DISTANCE` (4, the mini suite's rig, whose
  presets' world-unit values are thus the canonical ones);
* +z is the vertical of a rig without roll (`rig_vertical`: the direction orthogonal to every
  camera's right axis, exact for cameras levelled on a turntable, a light stage or a renderer's
  look-at, whose mean up leans towards the side that holds more cameras: 1.4° on a 30-camera
  synthetic scene), else the cameras' mean up direction (−y of OpenCV axes; the first camera's when
  the mean is shorter than `MIN_MEAN_UP`, e.g. cameras rolled every way); +x points from the origin
  towards the first camera, orthogonal to +z (the first camera's right axis when it sits on the z
  axis), +y = z × x.

Rigs without a centre are refused with a `RigError` saying why (`rig_centre`): cameras all at one
point (one pose, or turning about one spot: no parallax), axes that meet behind or among the cameras
(looking outwards), and a forward-facing rig without near/far distances (nothing gives the scene's
depth).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from olatbench.datasets.records import Camera, PointLight

#: The median distance from the cameras to the canonical origin, in canonical units.
CANONICAL_CAMERA_DISTANCE = 4.0
#: Below this length the cameras' mean up vector (mean of unit vectors) is not trusted: the first
#: camera's is used.
MIN_MEAN_UP = 0.3
#: `rig_vertical` trusts the right axes when they lie in one plane (smallest eigenvalue of Σ r rᵀ
#: below this share of the middle one: within ≈ 9° of it) and spread in it (middle eigenvalue above
#: this share of the camera count: over ≈ 45° of azimuth).
LEVEL_RIG_RATIO = 0.05
#: `rig_centre` takes the axes' nearest point when the axes spread about their mean by at least this
#: rms angle (degrees; below it their crossing is lost in a few pixels of pose noise: a
#: forward-facing rig) ...
MIN_AXES_SPREAD_DEG = 5.0
#: ... and that point lies ahead of the cameras: the median angle between a camera's axis and its
#: direction to the point is at most this (degrees; ≈ 0 for a rig looking at its object).
MAX_CENTRE_ANGLE_DEG = 60.0
#: Camera positions within this share of their distance from the world origin of each other are one
#: point.
SAME_POINT_RTOL = 1e-9


class RigError(ValueError):
    """Training cameras no canonical frame can be fitted to; the message says why and what would
    help."""


@dataclass(frozen=True, eq=False)
class Similarity:
    """``x -> scale · rotation @ x + translation``: ``scale`` > 0, ``rotation`` (3, 3) proper,
    ``translation`` (3,)."""

    scale: float
    rotation: np.ndarray
    translation: np.ndarray

    @classmethod
    def identity(cls) -> Similarity:
        return cls(1.0, np.eye(3), np.zeros(3))

    @property
    def is_identity(self) -> bool:
        return (
            self.scale == 1.0
            and np.array_equal(self.rotation, np.eye(3))
            and not np.any(self.translation)
        )

    def matrix(self) -> np.ndarray:
        """The 4×4 homogeneous matrix ``[[scale · R, t], [0, 1]]``."""
        out = np.eye(4)
        out[:3, :3] = self.scale * np.asarray(self.rotation, np.float64)
        out[:3, 3] = self.translation
        return out

    def inverse(self) -> Similarity:
        rotation_t = np.asarray(self.rotation, np.float64).T
        return Similarity(
            1.0 / self.scale, rotation_t, -(rotation_t @ self.translation) / self.scale
        )

    def then(self, other: Similarity) -> Similarity:
        """This transform followed by ``other``."""
        rotation = np.asarray(other.rotation, np.float64) @ self.rotation
        return Similarity(
            self.scale * other.scale,
            rotation,
            other.scale * (other.rotation @ self.translation) + other.translation,
        )

    def points(self, points: np.ndarray) -> np.ndarray:
        """Points (..., 3) -> (..., 3), float64."""
        return (
            self.scale * np.asarray(points, np.float64) @ np.asarray(self.rotation, np.float64).T
            + self.translation
        )

    def camera(self, camera: Camera) -> Camera:
        """The camera seeing the transformed world as ``camera`` saw the original
        (same image, same ``K``); the identity returns ``camera`` itself."""
        if self.is_identity:
            return camera
        c2w = np.eye(4)
        c2w[:3, :3] = (
            np.asarray(self.rotation, np.float64) @ np.asarray(camera.c2w, np.float64)[:3, :3]
        )
        c2w[:3, 3] = self.points(camera.position)
        near = None if camera.near is None else camera.near * self.scale
        far = None if camera.far is None else camera.far * self.scale
        return replace(camera, c2w=c2w, near=near, far=far)

    def light(self, light: PointLight) -> PointLight:
        """The light at the transformed position, intensity × scale² (same irradiance at transformed
        points); the identity returns ``light`` itself."""
        if self.is_identity:
            return light
        return replace(
            light,
            position=self.points(light.position),
            intensity=np.asarray(light.intensity, np.float64) * self.scale**2,
        )

    def log_scales(self, log_scales: np.ndarray) -> np.ndarray:
        """Gaussian log-scales (..., 3) after the transform (+ log(scale))."""
        return np.asarray(log_scales, np.float64) + np.log(self.scale)

    def quaternions(self, quats: np.ndarray) -> np.ndarray:
        """wxyz quaternions (..., 4) of local-to-world rotations -> those of ``R`` composed after
        them (not normalised: a quaternion's norm is kept, as the Gaussian core normalises on
        use)."""
        return quaternion_product(rotation_quaternion(self.rotation), np.asarray(quats, np.float64))

    def to_dict(self) -> dict[str, Any]:
        """Plain floats, for checkpoints and results files."""
        return {
            "scale": float(self.scale),
            "rotation": np.asarray(self.rotation, np.float64).tolist(),
            "translation": np.asarray(self.translation, np.float64).tolist(),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Similarity:
        return cls(
            float(data["scale"]),
            np.asarray(data["rotation"], np.float64),
            np.asarray(data["translation"], np.float64),
        )

    def allclose(self, other: Similarity, rtol: float = 1e-9) -> bool:
        """Equal to rounding (``rtol`` of the scale; rotation and translation relative to the
        translation's size)."""
        size = max(1.0, float(np.linalg.norm(self.translation)))
        return (
            abs(self.scale - other.scale) <= rtol * self.scale
            and np.allclose(self.rotation, other.rotation, rtol=0.0, atol=rtol)
            and np.allclose(self.translation, other.translation, rtol=0.0, atol=rtol * size)
        )


def rotation_quaternion(rotation: np.ndarray) -> np.ndarray:
    """The unit wxyz quaternion (4,) of a proper rotation matrix (3, 3), w ≥ 0
    (Shepperd's method)."""
    m = np.asarray(rotation, np.float64)
    trace = np.trace(m)
    candidates = np.array([trace, m[0, 0], m[1, 1], m[2, 2]])
    k = int(np.argmax(candidates))
    if k == 0:
        r = np.sqrt(1.0 + trace)
        q = (
            np.array([r, (m[2, 1] - m[1, 2]) / r, (m[0, 2] - m[2, 0]) / r, (m[1, 0] - m[0, 1]) / r])
            / 2.0
        )
    else:
        i, j, n = k - 1, k % 3, (k + 1) % 3
        r = np.sqrt(1.0 + m[i, i] - m[j, j] - m[n, n])
        q = np.empty(4)
        q[0] = (m[n, j] - m[j, n]) / r
        q[1 + i] = r
        q[1 + j] = (m[j, i] + m[i, j]) / r
        q[1 + n] = (m[n, i] + m[i, n]) / r
        q /= 2.0
    return q if q[0] >= 0 else -q


def quaternion_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a ⊗ b`` of wxyz quaternions (broadcast over leading axes): the rotation b,
    then a."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a, np.float64), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, np.float64), -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def unit_axes(cameras: Sequence[Camera], column: int) -> np.ndarray:
    """(N, 3) unit vectors of one camera axis in world coordinates, per camera: ``column`` 0 right,
    1 down, 2 the optical axis (OpenCV axes, the columns of ``c2w``)."""
    return np.stack([c.c2w[:3, column] / np.linalg.norm(c.c2w[:3, column]) for c in cameras])


def axes_centre(cameras: Sequence[Camera]) -> np.ndarray:
    """The point (3,) nearest, in least squares, to every camera's optical axis.

    When the axes do not pin it down (all parallel, or one camera), the solution nearest the
    cameras' mean centre along the free directions is taken, so the point still moves with the
    cameras under any similarity.
    """
    origins = np.stack([c.position for c in cameras])
    axes = unit_axes(cameras, 2)
    projector = np.eye(3)[None] - axes[:, :, None] * axes[:, None, :]  # (N, 3, 3) I - d dᵀ
    system, rhs = projector.sum(0), (projector @ origins[:, :, None]).sum(0)[:, 0]
    eigenvalues = np.linalg.eigvalsh(system)
    if eigenvalues[0] > 1e-9 * eigenvalues[-1]:
        return np.linalg.lstsq(system, rhs, rcond=None)[0]
    mean = origins.mean(0)  # solve for the offset from the mean, minimum norm: equivariant
    return mean + np.linalg.lstsq(system, rhs - system @ mean, rcond=1e-9)[0]


def rig_vertical(cameras: Sequence[Camera]) -> np.ndarray | None:
    """The unit vector (3,) orthogonal, in least squares, to every camera's right axis
    (+x of OpenCV axes), signed along the cameras' up: the vertical of a rig whose cameras have no
    roll. None when the right axes do not pin it down (`LEVEL_RIG_RATIO`: rolled cameras, or right
    axes nearly parallel, as in a forward-facing capture)."""
    rights = unit_axes(cameras, 0)
    values, vectors = np.linalg.eigh(rights.T @ rights)  # ascending
    if not (values[0] < LEVEL_RIG_RATIO * values[1] and values[1] > LEVEL_RIG_RATIO * len(cameras)):
        return None
    vertical = vectors[:, 0]
    up = -unit_axes(cameras, 1).sum(0)
    return vertical if vertical @ up >= 0.0 else -vertical


def rig_centre(cameras: Sequence[Camera]) -> np.ndarray:
    """The centre (3,) of the scene the ``cameras`` look at (module docstring), or a `RigError`
    naming why the rig has none: all at one point, axes meeting behind or among the cameras, or
    facing one way without near/far."""
    count = len(cameras)
    positions = np.stack([c.position for c in cameras])
    axes = unit_axes(cameras, 2)
    spread = float(np.max(np.linalg.norm(positions - positions.mean(0), axis=1)))
    if spread <= SAME_POINT_RTOL * float(np.max(np.linalg.norm(positions, axis=1))):
        if count == 1:
            raise RigError(
                "a single training camera: one view has no parallax, so no 3D scene can be fitted"
            )
        if np.all(axes @ axes[0] > 1.0 - 1e-9):
            raise RigError(
                f"all {count} training cameras have one pose (one position, one viewing "
                "direction): there is no parallax to fit a 3D scene to; check the "
                "transform_matrix of each frame"
            )
        raise RigError(
            f"all {count} training cameras sit at one point and only turn about it (a panorama): "
            "without parallax no 3D scene can be fitted"
        )
    mean_axis = axes.mean(0)
    system = count * np.eye(3) - axes.T @ axes  # Σ (I - d dᵀ)
    spread_deg = float(
        np.degrees(np.arcsin(np.sqrt(max(np.linalg.eigvalsh(system)[0], 0.0) / count)))
    )
    if spread_deg >= MIN_AXES_SPREAD_DEG:
        centre = axes_centre(cameras)
        towards = centre - positions
        lengths = np.linalg.norm(towards, axis=1)
        cosines = np.einsum("ij,ij->i", towards, axes) / np.where(lengths > 0, lengths, 1.0)
        angle = float(np.degrees(np.arccos(np.clip(np.median(cosines), -1.0, 1.0))))
        if angle <= MAX_CENTRE_ANGLE_DEG:
            return centre
        raise RigError(
            f"the optical axes of the {count} training cameras meet behind or among them (median "
            f"angle {angle:.0f}° between a camera's axis and that point, at most "
            f"{MAX_CENTRE_ANGLE_DEG:g}° fits): the cameras look outwards, and olatbench fits "
            "object-centric and forward-facing rigs"
        )
    if np.linalg.norm(mean_axis) < 0.9:
        raise RigError(
            f"the optical axes of the {count} training cameras are parallel but face opposite "
            "ways: no centre of the scene can be fitted"
        )
    nears = [c.near for c in cameras]
    fars = [c.far for c in cameras]
    if any(value is None for value in (*nears, *fars)):
        raise RigError(
            f"the {count} training cameras face one way (their axes within {spread_deg:.1f}° rms "
            f"of each other, under the {MIN_AXES_SPREAD_DEG:g}° that pins down where they meet) "
            "and the scene gives no camera_near/camera_far: the distance to the scene cannot be "
            "fitted; add camera_near and camera_far (the depth range of the scene, in scene "
            "units) to its transforms files"
        )
    depth = float(np.median((np.asarray(nears, np.float64) + np.asarray(fars, np.float64)) / 2.0))
    return positions.mean(0) + depth * mean_axis / np.linalg.norm(mean_axis)


def canonical_frame(cameras: Sequence[Camera]) -> Similarity:
    """The world -> canonical similarity of a scene fitted to its (training) ``cameras``
    (module docstring); a `RigError` for a rig without a centre (`rig_centre`)."""
    if not cameras:
        raise ValueError("the canonical frame needs at least one camera")
    centre = rig_centre(cameras)
    positions = np.stack([c.position for c in cameras])
    distance = float(np.median(np.linalg.norm(positions - centre, axis=1)))
    up = rig_vertical(cameras)
    if up is None:
        ups = -unit_axes(cameras, 1)
        up = ups.mean(0)
        if np.linalg.norm(up) < MIN_MEAN_UP:
            up = ups[0]
    z = up / np.linalg.norm(up)
    towards = positions[0] - centre
    x = towards - z * (z @ towards)
    # the first camera on the z axis: its right axis instead
    if np.linalg.norm(x) < 1e-6 * distance:
        right = cameras[0].c2w[:3, 0]
        x = right - z * (z @ right)
    x = x / np.linalg.norm(x)
    rotation = np.stack([x, np.cross(z, x), z])  # rows: the canonical axes in world coordinates
    scale = CANONICAL_CAMERA_DISTANCE / distance
    return Similarity(scale, rotation, -scale * (rotation @ centre))
