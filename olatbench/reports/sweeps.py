"""Relighting sweeps: camera and light trajectories around a scene, without a viewer.

Orbits rotate about the scene's up axis through its centre (`orbit_frame`): the centre is the
point nearest (least squares) to every camera's optical axis, the up axis the mean camera "up"
(−y in OpenCV axes). Trajectories (angles in degrees, endpoints excluded so a loop does not repeat a
frame):

* ``light-orbit``: the light sweeps 360° in azimuth in 2.4° steps (150 frames), camera fixed;
* ``view-orbit``: the camera turns 360° in 2° steps (180 frames), light fixed;
* ``paper``: the paper's appendix trajectory — light 360° in 2.4° steps, camera 180° to the back in
  2° steps, light 360° again, camera 180° back (150 + 90 + 150 + 90 = 480 frames).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from olatbench.datasets.records import Camera, PointLight

SWEEPS = ("light-orbit", "view-orbit", "paper")
LIGHT_STEP_DEG = 2.4
VIEW_STEP_DEG = 2.0


@dataclass(frozen=True)
class SweepFrame:
    """One frame of a sweep: the camera, the light and the phase it belongs to."""

    camera: Camera
    light: PointLight
    phase: str


def rotation_matrix(axis: np.ndarray, degrees: float) -> np.ndarray:
    """Right-handed rotation (3, 3) by ``degrees`` about the unit ``axis`` (Rodrigues)."""
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    angle = np.deg2rad(degrees)
    cross = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle) * cross + (1.0 - np.cos(angle)) * (cross @ cross)


def orbit_frame(cameras: Sequence[Camera]) -> tuple[np.ndarray, np.ndarray]:
    """(centre (3,), unit up (3,)) of a capture from its cameras (at least two non-parallel
    axes)."""
    if len(cameras) < 2:
        raise ValueError("orbit_frame needs at least two cameras to find the scene centre")
    system, rhs = np.zeros((3, 3)), np.zeros(3)
    for camera in cameras:
        direction = camera.c2w[:3, 2] / np.linalg.norm(camera.c2w[:3, 2])
        projector = np.eye(3) - np.outer(direction, direction)
        system += projector
        rhs += projector @ camera.position
    if np.linalg.matrix_rank(system) < 3:
        raise ValueError("the cameras' optical axes are parallel: the scene centre is undefined")
    centre = np.linalg.solve(system, rhs)
    up = -np.mean([camera.c2w[:3, 1] for camera in cameras], axis=0)
    norm = np.linalg.norm(up)
    if norm < 1e-8:
        raise ValueError("the cameras' up vectors cancel out: no common up axis")
    return centre, up / norm


def rotate_camera(camera: Camera, centre: np.ndarray, up: np.ndarray, degrees: float) -> Camera:
    """The camera turned by ``degrees`` about the axis ``up`` through ``centre``."""
    rotation = rotation_matrix(up, degrees)
    c2w = np.array(camera.c2w, dtype=np.float64)
    turned = np.eye(4)
    turned[:3, :3] = rotation @ c2w[:3, :3]
    turned[:3, 3] = centre + rotation @ (c2w[:3, 3] - centre)
    return replace(camera, c2w=turned)


def rotate_light(
    light: PointLight, centre: np.ndarray, up: np.ndarray, degrees: float
) -> PointLight:
    """The light moved by ``degrees`` about the axis ``up`` through ``centre``."""
    rotation = rotation_matrix(up, degrees)
    position = centre + rotation @ (np.asarray(light.position, dtype=np.float64) - centre)
    return replace(light, position=position)


def _steps(degrees: float, step: float) -> np.ndarray:
    return np.arange(1, round(degrees / step) + 1) * step  # excludes the start, reaches the end


def light_sweep(
    camera: Camera,
    light: PointLight,
    centre,
    up,
    degrees: float = 360.0,
    step: float = LIGHT_STEP_DEG,
    phase: str = "light",
) -> list[SweepFrame]:
    """The light turning ``degrees`` in ``step`` increments, starting at the given light
    (exclusive end)."""
    angles = np.concatenate([[0.0], _steps(degrees, step)[:-1]])
    return [SweepFrame(camera, rotate_light(light, centre, up, a), phase) for a in angles]


def view_sweep(
    camera: Camera,
    light: PointLight,
    centre,
    up,
    degrees: float,
    step: float = VIEW_STEP_DEG,
    phase: str = "view",
) -> list[SweepFrame]:
    """The camera turning ``degrees`` (signed) in ``step`` increments after the given camera."""
    sign = 1.0 if degrees >= 0 else -1.0
    return [
        SweepFrame(rotate_camera(camera, centre, up, sign * a), light, phase)
        for a in _steps(abs(degrees), step)
    ]


def trajectory(
    kind: str, camera: Camera, light: PointLight, centre: np.ndarray, up: np.ndarray
) -> list[SweepFrame]:
    """The frames of a named sweep (`SWEEPS`) starting from ``camera`` and ``light``."""
    if kind == "light-orbit":
        return light_sweep(camera, light, centre, up)
    if kind == "view-orbit":
        frames = [SweepFrame(camera, light, "view"), *view_sweep(camera, light, centre, up, 360.0)]
        return frames[:-1]
    if kind == "paper":
        frames = light_sweep(camera, light, centre, up, phase="light (front)")
        to_back = view_sweep(camera, light, centre, up, 180.0, phase="camera to back")
        back = to_back[-1].camera
        frames += to_back
        frames += light_sweep(back, light, centre, up, phase="light (back)")
        frames += view_sweep(back, light, centre, up, -180.0, phase="camera to front")
        return frames
    raise ValueError(f"unknown sweep {kind!r}; choose one of {', '.join(SWEEPS)}")


def subsample(frames: Sequence[SweepFrame], count: int | None) -> list[SweepFrame]:
    """``count`` frames spread evenly over the trajectory (all of them when ``count`` is None)."""
    if count is None or count >= len(frames):
        return list(frames)
    if count < 1:
        raise ValueError("the number of frames must be at least 1")
    indices = np.linspace(0, len(frames) - 1, count).round().astype(int)
    return [frames[i] for i in indices]
