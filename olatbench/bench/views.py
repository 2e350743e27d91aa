"""A job's training views as a method receives them: cameras, lights and frame ids, with or without
the images.

`load_views` reads the images (for training); `frame_views` gives the same views without them (for
restoring a trained method whose `Method.restore_needs_images` is false: a sweep or the viewer then
reads no training image). Both give the cameras resized to ``job.resolution``, the lights, the frame
ids in the split's order and the official background in the job's colour space, so per-view state a
method keeps (e.g. SSD-GS's pose and light refinements) is found for the same frames either way, and
the job's world -> canonical frame (`job_frame`, fitted to the training split; docs/architecture.md,
"The canonical frame").
"""

from __future__ import annotations

import dataclasses
import math
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from olatbench.bench.jobs import Job
from olatbench.datasets import colour
from olatbench.datasets.records import Camera, Frame
from olatbench.datasets.similarity import RigError, Similarity, canonical_frame
from olatbench.datasets.suites import FRAMES
from olatbench.methods.base import Views
from olatbench.progress import progress_bar

VIEWS_FILE = ".views.npy"
VIEWS_RAM_ENV = "OLATBENCH_VIEWS_RAM_GB"
VIEWS_HALF_ENV = "OLATBENCH_VIEWS_HALF_GB"


def view_camera(frame: Frame, job: Job) -> Camera:
    """The frame's camera at the job's resolution (the file's own size when the job has none)."""
    return frame.camera.resized(*job.resolution) if job.resolution else frame.camera


def job_frame(frames: list[Frame], job: Job) -> Similarity:
    """The world -> canonical similarity of ``job`` (`Views.frame`): `canonical_frame` of the
    training ``frames``' cameras when ``job.frame`` is "fitted", else the identity
    (the dataset's own frame)."""
    if job.frame == "dataset":
        return Similarity.identity()
    if job.frame != "fitted":
        raise ValueError(f"{job.folder}: unknown frame {job.frame!r} (known: {', '.join(FRAMES)})")
    try:
        return canonical_frame([frame.camera for frame in frames])
    # the plan refuses such a scene (bench.plan.check_rig); a job made by hand meets it here
    except RigError as error:
        raise RigError(f"{job.scene_path}: {error}") from None


def frame_views(frames: list[Frame], job: Job, frame: Similarity | None = None) -> Views:
    """The frames' cameras, lights, frame ids and background in ``job.colourspace``; ``images`` is
    None (nothing is read from the image files). ``frame``: the job's world -> canonical similarity,
    fitted to these frames (the training split) when not given; views of another split must be given
    the training split's."""
    if not frames:
        raise ValueError(f"{job.scene_path}: split '{job.train_split}' has no frames")
    first = frames[0]
    background = colour.convert_colourspace(
        np.asarray(first.background, np.float32), first.colourspace, job.colourspace
    )
    return Views(
        cameras=[view_camera(frame, job) for frame in frames],
        lights=[frame.light for frame in frames],
        images=None,
        frame_ids=[frame.frame_id for frame in frames],
        colourspace=job.colourspace,
        background=background,
        scene_name=job.scene,
        frame=job_frame(frames, job) if frame is None else frame,
    )


def load_views(
    frames: list[Frame],
    job: Job,
    progress: bool = False,
    position: int = 1,
    frame: Similarity | None = None,
) -> Views:
    """`frame_views` plus the images (composited on the official background, in the suite's colour
    space, resized to ``job.resolution``), loaded with a few threads into one preallocated array.

    Stacks whose float32 size exceeds ``$OLATBENCH_VIEWS_HALF_GB`` (default 2 GiB: every paper-scale
    scene, e.g. GS³'s 2000 views at 512² are 5.9 GiB; never a mini scene) are held as float16, which
    halves them at a rounding error ≤ 2⁻¹¹ relative (≤ 4.9e-4 on [0, 1], a quarter of an 8-bit
    step); methods receive float32 images per view either way, and the train split is then scored
    against the exact images from disk. Stacks still larger than ``$OLATBENCH_VIEWS_RAM_GB``
    (default 8 GiB; e.g. 2000 NRHints views at 1024² are 12.6 GB in float16) live in a memory-mapped
    file ``<job folder>/.views.npy`` instead of RAM; it is deleted when the job ends.
    """
    views = frame_views(frames, job, frame)
    resolution = tuple(job.resolution) if job.resolution else None

    def load(frame: Frame) -> np.ndarray:
        return frame.load(
            colourspace=job.colourspace, background="official", resolution=resolution
        ).rgb

    first_image = load(frames[0])
    shape = (len(frames), *first_image.shape)
    dtype = (
        np.float16
        if math.prod(shape) * 4 > float(os.environ.get(VIEWS_HALF_ENV, "2")) * 2**30
        else np.float32
    )
    if (
        math.prod(shape) * np.dtype(dtype).itemsize
        > float(os.environ.get(VIEWS_RAM_ENV, "8")) * 2**30
    ):
        images = np.lib.format.open_memmap(
            Path(job.folder) / VIEWS_FILE, mode="w+", dtype=dtype, shape=shape
        )
    else:
        images = np.empty(shape, dtype=dtype)

    def fill(index: int) -> None:
        image = first_image if index == 0 else load(frames[index])
        if image.shape != first_image.shape:
            raise ValueError(
                f"{frames[index].frame_id}: image is {image.shape[1]}×{image.shape[0]}, the first "
                f"view is {first_image.shape[1]}×{first_image.shape[0]}; pass --resolution WxH"
            )
        images[index] = image

    with ThreadPoolExecutor(max_workers=4) as pool:
        list(
            progress_bar(
                pool.map(fill, range(len(frames))),
                total=len(frames),
                desc=f"{job.scene}: loading views",
                position=position,
                leave=False,
                disable=not progress,
            )
        )
    return dataclasses.replace(views, images=images)
