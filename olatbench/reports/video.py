"""Render a relighting sweep of a finished job to an MP4 and a folder of PNG frames.

The trained method is rebuilt from the job's final checkpoint by `olatbench.bench.restore.restore`
(the runner's restore path: no training image is read for methods that need none), then
``method.render(camera, light)`` draws each frame. Renders are converted from the job's colour space
to sRGB and written as 8-bit PNGs (``<sweep>_frames/00000.png`` …) and an MP4
(`olatbench.reports.encode`: H.264 when PyAV or imageio-ffmpeg is installed, else OpenCV's ``mp4v``
with a logged warning).

A render owns the frames it wrote: the frame folder keeps their names in `FRAMES_RECORD`, and the
next render into that folder removes those it does not write again (a 2-frame orbit over a 4-frame
one leaves no frames 2–3); files it did not write there are never touched.

Under a lighting (`olatbench.datasets.lighting`: several lights, area lights, an environment map)
each frame is the sum in linear light of the method's renders under the lighting's point and
directional lights (`olatbench.bench.relight.Relighter`), encoded to sRGB; `render_still` writes one
such view as a PNG and a linear EXR.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from olatbench.atomic import atomic_path, write_json
from olatbench.datasets import colour
from olatbench.datasets.images import write_image
from olatbench.datasets.jsontext import parse_json
from olatbench.datasets.lights import parse_light
from olatbench.datasets.records import Camera, PointLight
from olatbench.names import did_you_mean
from olatbench.progress import progress_bar
from olatbench.reports.camera_paths import (
    CameraPathError,
    orbit_cameras,
    path_frames,
    read_camera_path,
    read_light_path,
)
from olatbench.reports.encode import open_video
from olatbench.reports.jobfolder import JobFolder, JobFolderError
from olatbench.reports.sweeps import SweepFrame, orbit_frame, subsample, trajectory

if TYPE_CHECKING:
    from olatbench.bench.relight import Relighter
    from olatbench.datasets.lighting import Lighting, SampledLights


class RenderRequestError(JobFolderError):
    """What was asked of a job is not there (a component its method does not render, a frame its
    scene lacks); the message says what there is."""


@dataclass(frozen=True)
class SweepOutput:
    """Where a sweep went: the video, the frame folder, the number of frames and the encoder used
    (`olatbench.reports.encode.ENCODERS`)."""

    video: Path
    frames_dir: Path
    frames: int
    encoder: str = ""


def load_trained_method(job: JobFolder, device: str = "cpu", progress: bool = True):
    """The job's trained method, rebuilt from its final checkpoint by
    `olatbench.bench.restore.restore` (which reads no training image for methods that need none); a
    `JobFolderError` says why it cannot be."""
    from olatbench.bench.restore import RestoreError, restore

    try:
        return restore(job.folder, device, progress=progress)[0]
    except RestoreError as error:
        raise JobFolderError(str(error)) from None


def load_relighter(job: JobFolder, device: str = "cpu", progress: bool = True) -> Relighter:
    """The job's trained method as a `olatbench.bench.relight.Relighter` (a `JobFolderError` says
    why it cannot be)."""
    from olatbench.bench.relight import RelightError, restore_relighter
    from olatbench.bench.restore import RestoreError

    try:
        return restore_relighter(job.folder, device, progress)[0]
    except (RestoreError, RelightError) as error:
        raise JobFolderError(str(error)) from None


def start_view(
    job: JobFolder, frame_id: str | None = None, resolution: tuple[int, int] | None = None
) -> tuple[Camera, PointLight, list]:
    """(the camera, at ``resolution`` or the job's, and the light of test frame ``frame_id``
    (default: the first; a training frame's id too), the training split's frames)."""
    scene = job.load_scene()
    frames = scene.split(job.job["test_split"])
    train = scene.split(job.job["train_split"])
    start = (
        frames[0]
        if frame_id is None
        else find_frame(frames, train, frame_id, job.job["scene_path"])
    )
    size = resolution or job.resolution
    return (start.camera.resized(*size) if size else start.camera), start.light, train


def sweep_frames(
    job: JobFolder,
    kind: str,
    frame_id: str | None = None,
    count: int | None = None,
    resolution: tuple[int, int] | None = None,
) -> list[SweepFrame]:
    """The sweep's cameras and lights, starting at a test frame (default: the first) of the job's
    scene."""
    camera, light, train = start_view(job, frame_id, resolution)
    centre, up = orbit_frame([frame.camera for frame in train])
    return subsample(trajectory(kind, camera, light, centre, up), count)


@dataclass(frozen=True)
class Orbit:
    """An orbit about the scene centre (`olatbench.reports.camera_paths.orbit_cameras`): elevation
    in degrees, radius in scene units (None: the training cameras' mean distance from the centre),
    number of frames."""

    elevation: float = 20.0
    radius: float | None = None
    frames: int = 120


def free_path_frames(
    job: JobFolder,
    *,
    camera_path: str | Path | None = None,
    orbit: Orbit | None = None,
    light: str | None = None,
    light_path: str | Path | None = None,
    resolution: tuple[int, int] | None = None,
) -> tuple[list[SweepFrame], float | None]:
    """The frames of a camera path (nerfstudio JSON) or an orbit, under ``light`` (a training light
    index or ``x,y,z``), the lights of ``light_path``, or by default the first test frame's light;
    and the path file's frame rate (None for an orbit). ``resolution`` resizes the cameras (default:
    the path's size; for an orbit the job's). Errors in what was asked are `RenderRequestError`s
    naming the file and field."""
    if (camera_path is None) == (orbit is None):
        raise RenderRequestError("give a camera path or an orbit (one of them)")
    scene = job.load_scene()
    test, train = scene.split(job.job["test_split"]), scene.split(job.job["train_split"])
    try:
        default = (
            parse_light(light, [frame.light for frame in train])
            if light is not None
            else test[0].light
        )
    except ValueError as error:  # not a training light index or a position
        raise RenderRequestError(str(error)) from None
    try:
        lights = read_light_path(light_path, default) if light_path is not None else [default]
        if camera_path is not None:
            read = read_camera_path(camera_path)
            cameras, fps, phase = read.cameras, read.fps, "camera path"
            if resolution:
                cameras = [camera.resized(*resolution) for camera in cameras]
        else:
            size = resolution or job.resolution
            template = test[0].camera.resized(*size) if size else test[0].camera
            centre, up = orbit_frame([frame.camera for frame in train])
            radius = orbit.radius or float(
                np.mean([np.linalg.norm(f.camera.position - centre) for f in train])
            )
            cameras = orbit_cameras(template, centre, up, orbit.elevation, radius, orbit.frames)
            fps, phase = None, "orbit"
        return path_frames(cameras, lights, phase), fps
    except CameraPathError as error:
        raise RenderRequestError(str(error)) from None


def find_frame(test: list, train: list, frame_id: str, scene_path: str):
    """The frame called ``frame_id``, searched in the ``test`` then the ``train`` split's frames; a
    `RenderRequestError` naming the close ids and the test split's range otherwise."""
    for frame in test + train:
        if frame.frame_id == frame_id:
            return frame
    ids = [frame.frame_id for frame in test + train]
    span = (
        f"{test[0].frame_id} … {test[-1].frame_id}" if len(test) > 1 else ids[0] if ids else "none"
    )
    raise RenderRequestError(
        f"{scene_path}: no frame {frame_id!r} in the test or train split"
        f"{did_you_mean(frame_id, ids)}; the test frames are {span} ({len(test)}), "
        "or leave --start-frame out to start at the first"
    )


def checked_component(output: dict, component: str, job: JobFolder) -> None:
    """A `RenderRequestError` listing what the method renders when ``component`` is not among its
    outputs."""
    if component not in output:
        raise RenderRequestError(
            f"method '{job.job['method']}' renders no component {component!r}"
            f"{did_you_mean(component, output)}; it renders {', '.join(sorted(output))} "
            "(choose one with --component)"
        )


def display_image(tensor, colourspace: str) -> np.ndarray:
    """A rendered output as it is shown: (H, W, 3) float32 sRGB in [0, 1]. Three-channel outputs
    (``rgb`` and the colour components) are converted from the job's ``colourspace``; one-channel
    maps (shadow, …) are shown as grey values as they are."""
    image = tensor.detach().to("cpu").float().numpy()
    if image.ndim == 2:
        image = image[..., None]
    if image.shape[2] == 1:
        image = np.repeat(image, 3, axis=2)
    else:
        image = colour.convert_colourspace(image, colourspace, "srgb")
    return np.clip(image, 0.0, 1.0)


#: In a frame folder: the names of the frames the last render wrote there (``{"frames":
#: ["00000.png", ...]}``).
FRAMES_RECORD = ".olatbench-frames.json"


def _recorded_frames(frames_dir: Path) -> list[str]:
    """The frame names the last render recorded in ``frames_dir`` (none when there is no readable
    record)."""
    try:
        names = parse_json((frames_dir / FRAMES_RECORD).read_text(encoding="utf-8")).get("frames")
    except (OSError, ValueError, AttributeError):
        return []
    return (
        [name for name in names if isinstance(name, str) and Path(name).name == name]
        if isinstance(names, list)
        else []
    )


def _own_frames(frames_dir: Path, previous: list[str], written: list[str]) -> None:
    """Remove the frames of the previous render that this one did not write again, and record this
    one's."""
    for name in sorted(set(previous) - set(written)):
        (frames_dir / name).unlink(missing_ok=True)
    write_json(frames_dir / FRAMES_RECORD, {"frames": written})


def render_sweep(
    job: JobFolder,
    kind: str,
    out_dir: str | Path,
    *,
    count: int | None = None,
    frame_id: str | None = None,
    component: str = "rgb",
    fps: float = 30.0,
    device: str = "cpu",
    resolution: tuple[int, int] | None = None,
    progress: bool = True,
    method=None,
    frames: list[SweepFrame] | None = None,
    video: str | Path | None = None,
    lighting: SampledLights | None = None,
) -> SweepOutput:
    """Render the sweep into ``out_dir`` (``<kind>.mp4`` and ``<kind>_frames/``); returns where.

    ``method`` and ``frames`` may be given to skip loading them from the job
    (tests, notebooks, the viewer); ``video`` names the MP4 instead (its frames then go to ``<video
    stem>_frames/`` beside it). With ``lighting`` every frame is its camera under those lights (its
    own light is not used; ``method``, if given, is then a `olatbench.bench.relight.Relighter`).
    """
    import torch

    out_dir = Path(out_dir)
    if lighting is not None and component != "rgb":
        raise RenderRequestError(
            f"under a lighting only 'rgb' adds up over lights, not {component!r}"
        )
    frames = frames if frames is not None else sweep_frames(job, kind, frame_id, count, resolution)
    if lighting is None:
        method = method if method is not None else load_trained_method(job, device, progress)
    elif method is None:
        method = load_relighter(job, device, progress)
    video_path = Path(video) if video is not None else out_dir / f"{kind}.mp4"
    frames_dir = video_path.with_name(f"{video_path.stem}_frames")
    frames_dir.mkdir(parents=True, exist_ok=True)
    previous = _recorded_frames(frames_dir)
    width, height = frames[0].camera.width, frames[0].camera.height
    with atomic_path(video_path) as temporary:
        writer = open_video(temporary, fps, width, height)
        try:
            with torch.no_grad():
                for index, frame in enumerate(
                    progress_bar(frames, desc=f"{job.label}: {kind}", disable=not progress)
                ):
                    if lighting is not None:
                        image = method.display(frame.camera, lighting)
                    else:
                        output = method.render(frame.camera, frame.light)
                        checked_component(output, component, job)
                        image = display_image(output[component], job.job["colourspace"])
                    write_image(frames_dir / f"{index:05d}.png", image)
                    writer.write(colour.quantize_8bit(image))
        finally:
            writer.close()
    _own_frames(frames_dir, previous, [f"{index:05d}.png" for index in range(len(frames))])
    return SweepOutput(video_path, frames_dir, len(frames), writer.encoder)


def sample_lighting(
    job: JobFolder, lighting: Lighting, samples: int | None = None
) -> SampledLights:
    """The point and directional lights of ``lighting`` for the job's scene: maps without an ``up``
    are stood on the vertical of the training cameras' rig
    (`olatbench.bench.relight.LightingReference`), ``samples`` overrides every area light's and
    map's count; a map that cannot be read is a `RenderRequestError` naming the file."""
    from olatbench.bench.relight import LightingReference, RelightError
    from olatbench.datasets.errors import DatasetError

    train = job.load_scene().split(job.job["train_split"])
    try:
        up = LightingReference.of(
            [frame.camera for frame in train], [frame.light for frame in train]
        ).up
        return lighting.sample(up, samples)
    except (DatasetError, RelightError) as error:
        raise RenderRequestError(str(error)) from None


@dataclass(frozen=True)
class StillOutput:
    """Where a still went: the sRGB PNG and the linear EXR (the job's images' colour decoded to
    linear light)."""

    png: Path
    exr: Path


def render_still(
    job: JobFolder,
    lighting: SampledLights,
    out_dir: str | Path,
    name: str,
    *,
    frame_id: str | None = None,
    device: str = "cpu",
    resolution: tuple[int, int] | None = None,
    progress: bool = True,
    relighter: Relighter | None = None,
) -> StillOutput:
    """One view under ``lighting``: the camera of test frame ``frame_id`` (default: the first),
    written as ``<name>.png`` (sRGB, 8-bit) and ``<name>.exr`` (linear, float) in ``out_dir``."""
    from olatbench.bench.relight import shown

    camera = start_view(job, frame_id, resolution)[0]
    relighter = relighter if relighter is not None else load_relighter(job, device, progress)
    linear = relighter.linear(camera, lighting, progress)
    out_dir = Path(out_dir)
    return StillOutput(
        write_image(out_dir / f"{name}.png", shown(linear)),
        write_image(out_dir / f"{name}.exr", linear, bit_depth="float"),
    )
