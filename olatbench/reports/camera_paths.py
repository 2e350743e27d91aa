"""Free camera paths for `olatbench render`: a nerfstudio camera-path JSON or an orbit, under a
chosen light or a light path.

**nerfstudio's camera-path JSON** (what its viewer's "Render" panel exports and
``ns-render camera-path`` reads, ``nerfstudio/cameras/camera_paths.py`` ``get_path_from_json``):
``render_width`` and ``render_height`` (pixels), ``fps``, ``seconds``, and ``camera_path``, a list
of frames, each with ``camera_to_world`` (the 4×4 matrix flattened row-major, **OpenGL camera
axes**: x right, y up, z backward) and ``fov`` (the **vertical** field of view in degrees; its
``aspect`` is implied by the image size). Its cameras are pinhole with square pixels and the
principal point at the image centre: fx = fy = (render_height / 2) / tan(fov / 2), cx = width / 2,
cy = height / 2 (a three.js perspective camera). Other ``camera_type`` values
(fisheye, equirectangular) are refused. The matrices are read in the scene's world frame as
olatbench loads it (the frame of the training cameras); the axes are converted once, by
`olatbench.datasets.cameras`.

**Orbit**: ``count`` cameras on a circle about the scene's up axis through its centre
(`sweeps.orbit_frame`), at ``elevation`` degrees above the plane through the centre and ``radius``
scene units from it, looking at the centre, starting at the azimuth of a template camera whose
intrinsics and size they keep.

**Lights**: one light for every frame (`olatbench.datasets.lights.parse_light`: a training frame's
light by its index in the training split, or a position ``x,y,z`` in world units with the first
training light's intensity), or a light-path JSON: ``{"lights": [{"position": [x, y, z],
"intensity": [r, g, b]}, ...]}`` (intensity optional: the first training light's; each channel ≥ 0),
one light per camera, or one for all.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.datasets.cameras import focal_from_fov, intrinsics_matrix, look_at, opengl_to_opencv
from olatbench.datasets.records import Camera, PointLight
from olatbench.datasets.sizes import checked_side
from olatbench.reports.sweeps import SweepFrame


class CameraPathError(ValueError):
    """A camera-path or light-path file, or a light, that cannot be used; the message names the file
    and field."""


@dataclass(frozen=True)
class CameraPath:
    """The cameras of a camera-path file and its frame rate (frames per second; None when the file
    has none)."""

    cameras: list[Camera]
    fps: float | None


def _number(value: Any, where: str, positive: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise CameraPathError(f"{where}: expected a finite number, not {value!r}")
    if positive and value <= 0:
        raise CameraPathError(f"{where}: must be positive, not {value!r}")
    return float(value)


def _side(value: Any, where: str) -> int:
    """An image side in pixels (`olatbench.datasets.sizes.checked_side`), checked before anything is
    rendered."""
    try:
        return checked_side(value)
    except ValueError as error:
        raise CameraPathError(f"{where}: {error}") from None


def _vector(value: Any, size: int, where: str) -> np.ndarray:
    if not isinstance(value, list | tuple) or len(value) != size:
        raise CameraPathError(f"{where}: expected a list of {size} numbers, not {value!r}")
    return np.array([_number(item, where, positive=False) for item in value], dtype=np.float64)


def _read_json(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CameraPathError(f"{path}: not found") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise CameraPathError(f"{path}: cannot be read as JSON ({error})") from None
    if not isinstance(data, dict):
        raise CameraPathError(f"{path}: expected a JSON object")
    return data


def read_camera_path(path: str | Path) -> CameraPath:
    """The cameras (OpenCV axes, `olatbench.datasets.records.Camera`) of a nerfstudio camera-path
    JSON file."""
    path = Path(path)
    data = _read_json(path)
    camera_type = data.get("camera_type", "perspective")
    if camera_type != "perspective":
        raise CameraPathError(
            f"{path}: camera_type {camera_type!r}; only 'perspective' paths can be rendered"
        )
    for key in ("render_width", "render_height", "camera_path"):
        if key not in data:
            raise CameraPathError(
                f"{path}: missing field '{key}' (a nerfstudio camera path has render_width, "
                "render_height and camera_path)"
            )
    width, height = (
        _side(data[key], f"{path}: {key}") for key in ("render_width", "render_height")
    )
    frames = data["camera_path"]
    if not isinstance(frames, list) or not frames:
        raise CameraPathError(f"{path}: camera_path must be a non-empty list of frames")
    cameras = []
    for index, frame in enumerate(frames):
        where = f"{path}: camera_path[{index}]"
        if not isinstance(frame, dict) or "camera_to_world" not in frame or "fov" not in frame:
            raise CameraPathError(f"{where}: expected an object with camera_to_world and fov")
        # row-major
        c2w = _vector(frame["camera_to_world"], 16, f"{where}.camera_to_world").reshape(4, 4)
        if (
            not np.allclose(c2w[3], [0.0, 0.0, 0.0, 1.0])
            or abs(np.linalg.det(c2w[:3, :3]) - 1.0) > 1e-3
        ):
            raise CameraPathError(
                f"{where}.camera_to_world: not a rigid transform (rotation and translation, last "
                "row 0 0 0 1)"
            )
        fov = _number(frame["fov"], f"{where}.fov")
        if fov >= 180.0:
            raise CameraPathError(
                f"{where}.fov: {fov} degrees; a perspective field of view is below 180"
            )
        # vertical field of view: the image height
        focal = focal_from_fov(math.radians(fov), height)
        K = intrinsics_matrix(focal, focal, width / 2.0, height / 2.0)
        cameras.append(Camera(K=K, c2w=opengl_to_opencv(c2w), width=width, height=height))
    fps = _number(data["fps"], f"{path}: fps") if data.get("fps") is not None else None
    return CameraPath(cameras, fps)


def orbit_cameras(
    template: Camera,
    centre: np.ndarray,
    up: np.ndarray,
    elevation: float,
    radius: float,
    count: int,
) -> list[Camera]:
    """``count`` cameras evenly spaced over 360° about ``up`` through ``centre`` (the last one
    before the first again), ``elevation`` degrees above the plane through ``centre`` normal to
    ``up``, ``radius`` from ``centre``, looking at it; they keep ``template``'s intrinsics and size
    and start at its azimuth."""
    if count < 1 or radius <= 0 or not -90.0 < elevation < 90.0:
        raise CameraPathError(
            f"an orbit needs at least one frame, a positive radius and an elevation strictly "
            f"between -90 and 90 degrees (got {count}, {radius}, {elevation})"
        )
    centre, up = np.asarray(centre, dtype=np.float64), np.asarray(up, dtype=np.float64)
    up = up / np.linalg.norm(up)
    start = template.position - centre
    start = start - (start @ up) * up  # the template's azimuth, in the plane normal to up
    if np.linalg.norm(start) < 1e-9:  # the template sits on the axis: any direction in the plane
        start = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
    first = start / np.linalg.norm(start)
    second = np.cross(up, first)
    cameras = []
    for azimuth in np.arange(count) * (2.0 * np.pi / count):
        around = math.cos(azimuth) * first + math.sin(azimuth) * second
        direction = (
            math.cos(math.radians(elevation)) * around + math.sin(math.radians(elevation)) * up
        )
        cameras.append(replace(template, c2w=look_at(centre + radius * direction, centre, up)))
    return cameras


def read_light_path(path: str | Path, default: PointLight) -> list[PointLight]:
    """The lights of a light-path JSON file (module docstring); a missing intensity is
    ``default``'s."""
    path = Path(path)
    lights = _read_json(path).get("lights")
    if not isinstance(lights, list) or not lights:
        raise CameraPathError(
            f"{path}: expected a non-empty list 'lights' of {{\"position\": [x, y, z]}}"
        )
    result = []
    for index, light in enumerate(lights):
        where = f"{path}: lights[{index}]"
        if not isinstance(light, dict) or "position" not in light:
            raise CameraPathError(f"{where}: expected an object with a position")
        position = _vector(light["position"], 3, f"{where}.position")
        intensity = (
            _vector(light["intensity"], 3, f"{where}.intensity") if "intensity" in light else None
        )
        # as the scenes' pl_intensity (datasets: as_rgb)
        if intensity is not None and np.any(intensity < 0):
            raise CameraPathError(
                f"{where}.intensity: must be ≥ 0 in every channel (an RGB radiant intensity), "
                f"not {light['intensity']!r}"
            )
        result.append(
            replace(default, position=position)
            if intensity is None
            else PointLight(position, intensity, intensity_known=True)
        )
    return result


def path_frames(cameras: list[Camera], lights: list[PointLight], phase: str) -> list[SweepFrame]:
    """One `SweepFrame` per camera, with the one light or its own of as many lights."""
    if len(lights) not in (1, len(cameras)):
        raise CameraPathError(
            f"the light path has {len(lights)} lights for {len(cameras)} cameras; give one "
            "light per camera, or one for all"
        )
    lights = lights * len(cameras) if len(lights) == 1 else lights
    return [SweepFrame(camera, light, phase) for camera, light in zip(cameras, lights, strict=True)]


__all__ = [
    "CameraPath",
    "CameraPathError",
    "orbit_cameras",
    "path_frames",
    "read_camera_path",
    "read_light_path",
]
