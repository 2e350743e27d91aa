"""olatbench's scene -> the files an official loader reads, and its renders -> olatbench's frame
ids.

The converted scene holds the suite's train split as ``train`` and its test split as ``test`` (and,
for loaders that open ``transforms_val.json``, the test frames again as ``val``), in the source
order, at the job's resolution (cameras resized with `Camera.resized`, images area-resized by
`Frame.load`), each frame's image named after its frame id (`safe_file_stem`). A loader that reads
one camera model for all frames (NRHints' data/data_parser.py:41-66: intrinsics and
``camera_near``/``camera_far`` of the first split only, near/far defaulting to 3 and 10) gets scenes
whose frames share one camera or a clear refusal, and the scene's bounds when it has none.

A render script numbers its renders by the frame order of the transforms file it read
(`OfficialCode.render_order`: the converted ``transforms_test.json``, or e.g. the refined cameras
``train.py`` saved in its own shuffled order). `pair_renders` reads that file after the run and
pairs render ``i`` with the frame named by its ``i``-th entry (``img_path`` or ``file_path``), so no
pairing rests on olatbench's order of the split.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from olatbench.datasets.convert import write_scene
from olatbench.datasets.formats._common import safe_file_stem
from olatbench.datasets.records import Frame, Scene
from olatbench.methods.official.code import OfficialCode
from olatbench.methods.official.process import OfficialRunError


def unit_sphere_bounds(frames: list[Frame]) -> tuple[float, float]:
    """(near, far) that hold the unit sphere around the origin from every camera of ``frames``: the
    range NRHints samples its rays in (camera/ray_generator.py:133-139 clips them to that sphere);
    near stays > 0."""
    distances = [float(np.linalg.norm(frame.camera.position)) for frame in frames]
    return max(min(distances) - 1.0, 0.05 * min(distances), 1e-3), max(distances) + 1.0


def single_camera_model(
    code: OfficialCode, frames: list[Frame], scene: str
) -> tuple[float, float] | None:
    """For a loader that reads one camera model for every split (``code.single_camera_model``):
    check that all ``frames`` share intrinsics and size (`OfficialRunError` naming a frame that does
    not), and return the (near, far) to write when some frame has none (`unit_sphere_bounds`); None
    when nothing is to be filled in."""
    if not code.single_camera_model or not frames:
        return None
    first = frames[0].camera
    for frame in frames:
        camera = frame.camera
        if (camera.width, camera.height) != (first.width, first.height) or not np.allclose(
            camera.K, first.K
        ):
            raise OfficialRunError(
                f"{code.name}: its loader takes one camera model (intrinsics and image size of the "
                f"first split's file) for every frame, but scene {scene} has frames with "
                f"different ones: {frames[0].split}/{frames[0].frame_id} (fx {first.fx:g}, "
                f"{first.width}×{first.height}) and {frame.split}/{frame.frame_id} (fx "
                f"{camera.fx:g}, {camera.width}×{camera.height}); run it on a suite whose frames "
                "share one camera"
            )
    if all(frame.camera.near is not None and frame.camera.far is not None for frame in frames):
        return None
    return unit_sphere_bounds(frames)


def converted_scene(
    source: Scene,
    train_split: str,
    test_split: str,
    resolution: tuple[int, int] | None,
    with_val: bool = False,
    near_far: tuple[float, float] | None = None,
) -> tuple[Scene, dict[int, Frame]]:
    """The scene to write (splits renamed ``train`` / ``test`` [/ ``val``], cameras resized and
    given ``near_far`` when set) and, for the pixels, each written frame's source frame
    (by ``id``)."""
    originals: dict[int, Frame] = {}

    def resized(frame: Frame) -> Frame:
        camera = frame.camera.resized(*resolution) if resolution else frame.camera
        if near_far is not None:
            camera = dataclasses.replace(camera, near=near_far[0], far=near_far[1])
        copy = dataclasses.replace(frame, camera=camera)
        originals[id(copy)] = frame
        return copy

    frames = {
        "train": [resized(f) for f in source.split(train_split)],
        "test": [resized(f) for f in source.split(test_split)],
    }
    if with_val:
        frames["val"] = [resized(f) for f in source.split(test_split)]
    scene = Scene(
        name=source.name,
        format=source.format,
        root=source.root,
        frames=frames,
        background=source.background,
        metadata=dict(source.metadata),
    )
    return scene, originals


def write_for_code(
    code: OfficialCode,
    source: Scene,
    out_dir: Path,
    suite: str,
    train_split: str,
    test_split: str,
    resolution: tuple[int, int] | None,
) -> Path:
    """Write ``source`` where and how ``code``'s loader reads it for ``suite``
    (replacing an earlier copy)."""
    near_far = single_camera_model(
        code, [*source.split(train_split), *source.split(test_split)], source.name
    )
    scene, originals = converted_scene(
        source, train_split, test_split, resolution, code.needs_val_split, near_far
    )

    def pixels(frame: Frame) -> np.ndarray:
        image = originals[id(frame)].load(
            colourspace="linear", background=None, resolution=resolution
        )
        alpha = image.alpha if image.alpha is not None else np.ones(image.rgb.shape[:2], np.float32)
        return np.concatenate([image.rgb, alpha[..., None]], axis=2).astype(np.float32)

    return write_scene(scene, out_dir, code.data_format(suite), pixels, overwrite=True)


def _entry_stem(entry: Mapping[str, object]) -> str | None:
    """The image file stem a transforms-file frame names: ``img_path``'s (a path with extension, as
    SSD-GS and GS³ save it) or ``file_path``'s last part (written without extension)."""
    if isinstance(entry.get("img_path"), str):
        return Path(str(entry["img_path"])).stem
    if isinstance(entry.get("file_path"), str):
        return Path(str(entry["file_path"])).name
    return None


def pair_renders(
    code: OfficialCode, order_file: Path, frame_ids: list[str], values: Mapping[str, object]
) -> dict[str, Path]:
    """``{frame id: path of its render}``: render ``i`` (``code.renders`` with ``{index}`` = i)
    shows the frame of the ``i``-th entry of ``order_file``, the transforms file the render script
    read (module docstring).

    `OfficialRunError` when the file is missing or unreadable, names an image that is no test frame,
    names one twice, or leaves a test frame out."""
    stems = {safe_file_stem(frame_id): frame_id for frame_id in frame_ids}
    if len(stems) != len(frame_ids):
        raise OfficialRunError(
            f"{code.name}: test frames share an image file name, so renders cannot be paired "
            f"with them: {sorted(frame_ids)}"
        )
    try:
        entries = json.loads(Path(order_file).read_text(encoding="utf-8"))["frames"]
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise OfficialRunError(
            f"{code.name}: cannot read the frame order of the renders from {order_file} "
            f"({type(error).__name__}: {error})"
        ) from None
    paired: dict[str, Path] = {}
    for index, entry in enumerate(entries):
        stem = _entry_stem(entry) if isinstance(entry, Mapping) else None
        frame_id = stems.get(stem) if stem is not None else None
        if frame_id is None or frame_id in paired:
            problem = (
                "names no image"
                if stem is None
                else (
                    f"names {stem!r} a second time"
                    if frame_id in paired
                    else f"names {stem!r}, no test frame"
                )
            )
            raise OfficialRunError(
                f"{code.name}: {order_file}, frame {index} {problem}; renders cannot be paired"
            )
        paired[frame_id] = Path(code.renders.format_map({**values, "index": index}))
    left_out = [frame_id for frame_id in frame_ids if frame_id not in paired]
    if left_out:
        raise OfficialRunError(
            f"{code.name}: {order_file} lists {len(paired)} of the {len(frame_ids)} test frames; "
            f"left out, e.g. {', '.join(left_out[:5])}"
        )
    return {frame_id: paired[frame_id] for frame_id in frame_ids}


# mean absolute difference: 8-bit rounding of the loader's composite
GROUND_TRUTH_TOLERANCE = 2.0 / 255


def check_ground_truths(code: OfficialCode, order_file: Path, values: Mapping[str, object]) -> None:
    """Check that the ground truth the render script wrote for render ``i``
    (``code.render_ground_truths``) is the image of the ``i``-th frame of ``order_file`` composited
    over black or white, as the loader composites (mean absolute difference at most
    `GROUND_TRUTH_TOLERANCE`): what the script says it rendered each view for confirms the pairing
    of `pair_renders`. `OfficialRunError` naming the render, the frame and the file otherwise;
    nothing to check when the code writes no ground truths."""
    from olatbench.datasets.images import read_image

    if not code.render_ground_truths:
        return
    entries = json.loads(Path(order_file).read_text(encoding="utf-8"))["frames"]
    for index, entry in enumerate(entries):
        written_path = Path(code.render_ground_truths.format_map({**values, "index": index}))
        source = Path(order_file).parent / (
            str(entry["file_path"]) + str(entry.get("file_ext", ".png"))
        )
        if not written_path.is_file():
            raise OfficialRunError(
                f"{code.name}: the render script wrote no ground truth for render {index} "
                f"({written_path} is missing)"
            )
        written = read_image(written_path)[..., :3]
        image = read_image(source)
        rgb, alpha = (
            image[..., :3],
            image[..., 3:4] if image.shape[-1] == 4 else np.ones_like(image[..., :1]),
        )
        if written.shape != rgb.shape:
            raise OfficialRunError(
                f"{code.name}: the ground truth {written_path} of render {index} is "
                f"{written.shape[1]}×{written.shape[0]}, frame {source.stem} {rgb.shape[1]}×"
                f"{rgb.shape[0]}"
            )
        error = min(
            float(np.abs(written - (rgb * alpha + background * (1 - alpha))).mean())
            for background in (0.0, 1.0)
        )
        if error > GROUND_TRUTH_TOLERANCE:
            raise OfficialRunError(
                f"{code.name}: render {index} was rendered for another image than frame "
                f"{source.stem}, the {index}-th of {order_file}: the ground truth the script wrote "
                f"with it ({written_path}) differs from that frame's image by {error:.3f} on "
                "average; renders cannot be paired"
            )
