"""SSS-GS (Dihlmann et al. 2025) synthetic subsurface-scattering scenes (the public 256² release).

Files: ``transforms_{train,test}.json`` and the held-out split, named ``transforms_eval.json`` by
the dataset card (huggingface.co/datasets/CGTuebingen/SSS-GS) and ``transforms_val.json`` in copies
seen elsewhere: both are read, as splits ``eval`` and ``val``. The ``sssgs`` suite trains on
``train`` and scores ``test``; neither held-out split is used by it. The frames of every file are
*cameras*, each with lists ``file_paths`` and ``light_positions``
(and optionally ``light_intensities``), ``width``/``height`` and per-frame ``fl_x``, ``fl_y``,
``cx``, ``cy`` (or a top-level ``camera_angle_x``). Every (camera, light) pair becomes one record.
``exclude_list.txt`` names images to skip. Light positions are used as stored: the official loader
flips y and z twice (reader and dataset), which cancels. Without ``light_intensities`` the intensity
is unknown (1). Images: sRGB PNG, straight alpha, official background black. A PNG referenced by
several records is counted in ``Scene.metadata["shared_images"]``.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.atomic import write_json
from olatbench.datasets import colour
from olatbench.datasets.cameras import focal_from_fov, intrinsics_matrix, opencv_to_opengl
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.files import present, require_file
from olatbench.datasets.formats import _common as c
from olatbench.datasets.formats._suite import SuiteDefaults, default_aliases
from olatbench.datasets.formats.nrhints import _encode
from olatbench.datasets.records import Camera, Frame, PointLight, Scene

FORMAT_NAME = "sssgs"
DISPLAY_COLOURSPACE = "srgb"  # trained and scored in: 8-bit sRGB PNGs, used as stored
_SCENES = ("Bunny", "Candle", "Dragon", "Soap", "Statue")
#: The paper's SSS-GS suite (the public 256² down-scaled release).
SUITE_DEFAULTS = SuiteDefaults(
    scenes=_SCENES,
    aliases=default_aliases(_SCENES, {f"{s.lower()}_small": s for s in _SCENES}),
    resolution=(256, 256),
    iterations=60_000,
    protocol="ssdgs",
)
SPLIT_FILES = {
    "train": "transforms_train.json",
    "val": "transforms_val.json",
    "eval": "transforms_eval.json",
    "test": "transforms_test.json",
}
EXCLUDE_FILE = "exclude_list.txt"
DEFAULT_EXT = ".png"


def detect(root: Path) -> bool:
    """A tree whose frames hold ``file_paths`` / ``light_positions`` lists."""
    found = c.first_frame(Path(root), tuple(SPLIT_FILES.values()))
    return found is not None and ("file_paths" in found[2] or "light_positions" in found[2])


def _exclude_list(root: Path) -> set[str]:
    """Image names to skip (``.png`` stripped, as the official loader does)."""
    path = root / EXCLUDE_FILE
    if not present(path):
        return set()
    require_file(path, "text file")
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as error:
        raise DatasetError(f"cannot read ({error})", path=path) from None
    return {line.strip().replace(".png", "") for line in lines if line.strip()}


def _camera(raw: Mapping[str, Any], fov_x: float | None, *, path: Path, frame: int) -> Camera:
    where = {"path": path, "frame": frame}
    width = int(c.as_positive(c.require(raw, "width", **where), key="width", **where))
    height = int(c.as_positive(c.require(raw, "height", **where), key="height", **where))
    if fov_x is not None:
        fx = fy = focal_from_fov(fov_x, width)
    else:
        fx = c.as_positive(c.require(raw, "fl_x", **where), key="fl_x", **where)
        fy = c.as_positive(c.require(raw, "fl_y", **where), key="fl_y", **where)
    cx = (
        float(c.as_array(raw["cx"], (), key="cx", **where))
        if raw.get("cx") is not None
        else width / 2.0
    )
    cy = (
        float(c.as_array(raw["cy"], (), key="cy", **where))
        if raw.get("cy") is not None
        else height / 2.0
    )
    c2w = c.opencv_c2w(c.require(raw, "transform_matrix", **where), **where)
    return Camera(K=intrinsics_matrix(fx, fy, cx, cy), c2w=c2w, width=width, height=height)


def _records(
    root: Path, path: Path, raw: Mapping[str, Any], index: int, camera: Camera, excluded: set[str]
) -> tuple[list[tuple[str, Path, PointLight]], int]:
    """(stem, image, light) of one camera frame, and how many of its images the exclude list
    removed."""
    where = {"path": path, "frame": index}
    file_paths = c.require(raw, "file_paths", **where)
    positions = c.require(raw, "light_positions", **where)
    intensities = raw.get("light_intensities")
    for key, value in (
        ("file_paths", file_paths),
        ("light_positions", positions),
        ("light_intensities", intensities),
    ):
        if value is not None and not isinstance(value, list):
            raise DatasetError("expected a list", key=key, **where)
    if len(file_paths) != len(positions) or (
        intensities is not None and len(intensities) != len(positions)
    ):
        raise DatasetError(
            f"list lengths differ: {len(file_paths)} file_paths, {len(positions)} light_positions"
            + (f", {len(intensities)} light_intensities" if intensities is not None else ""),
            key="file_paths",
            **where,
        )
    records, skipped = [], 0
    for light_index, (file_path, position) in enumerate(zip(file_paths, positions, strict=True)):
        if isinstance(file_path, str) and file_path.split("/")[-1].replace(".png", "") in excluded:
            skipped += 1
            continue
        image = c.image_file(
            root, file_path, None, DEFAULT_EXT, key=f"file_paths[{light_index}]", **where
        )
        pos = c.as_array(position, (3,), key=f"light_positions[{light_index}]", **where)
        if intensities is not None:
            light = PointLight(
                position=pos,
                intensity=c.as_rgb(
                    intensities[light_index], key=f"light_intensities[{light_index}]", **where
                ),
                intensity_known=True,
            )
        else:
            light = PointLight(position=pos, intensity=np.ones(3), intensity_known=False)
        records.append((Path(str(file_path)).stem, image, light))
    return records, skipped


def read_scene(root: Path, errors: list[DatasetError] | None = None) -> Scene:
    """Read an SSS-GS scene folder, one record per (camera, light)."""
    root = Path(root)
    name = SUITE_DEFAULTS.canonical(root.name) or root.name
    excluded = _exclude_list(root)
    frames: dict[str, list[Frame]] = {}
    references: Counter[Path] = Counter()
    skipped = 0
    background = np.zeros(3)
    files = c.split_files(root, SPLIT_FILES)
    if not files:
        raise DatasetError(f"no {', '.join(SPLIT_FILES.values())}", path=root)
    for split, path in files.items():
        meta = c.read_json(path)
        fov_x = (
            c.as_positive(meta["camera_angle_x"], path=path, frame=None, key="camera_angle_x")
            if meta.get("camera_angle_x") is not None
            else None
        )
        pending: list[tuple[str, Path, PointLight, Camera]] = []
        for index, raw in enumerate(c.frames_of(meta, path)):
            try:
                camera = _camera(raw, fov_x, path=path, frame=index)
                records, n_skipped = _records(root, path, raw, index, camera, excluded)
            except DatasetError as error:
                if errors is None:
                    raise
                errors.append(error)
                continue
            skipped += n_skipped
            pending.extend((stem, image, light, camera) for stem, image, light in records)
        ids = c.unique_ids([stem for stem, *_ in pending])
        frames[split] = [
            Frame(
                scene=name,
                split=split,
                frame_id=frame_id,
                image_path=image,
                camera=camera,
                light=light,
                colourspace="srgb",
                alpha_mode="straight",
                background=background.copy(),
            )
            for frame_id, (_, image, light, camera) in zip(ids, pending, strict=True)
        ]
        references.update(image for _, image, _, _ in pending)
    shared = {image: n for image, n in references.items() if n > 1}
    metadata = {
        "folder": root.name,
        "files": {s: p.name for s, p in files.items()},
        "excluded_images": skipped,
        "exclude_list": len(excluded),
        "shared_images": len(shared),
        "shared_records": sum(shared.values()),
    }
    return Scene(
        name=name,
        format=FORMAT_NAME,
        root=root,
        frames=frames,
        background=background,
        metadata=metadata,
    )


def _same_camera(a: Camera, b: Camera) -> bool:
    return (
        (a.width, a.height) == (b.width, b.height)
        and np.allclose(a.K, b.K)
        and np.allclose(a.c2w, b.c2w)
    )


def write_scene(scene: Scene, out_dir: Path, pixels: Callable[[Frame], np.ndarray]) -> Path:
    """Write SSS-GS files: consecutive records of one camera become one JSON frame; 8-bit sRGB RGBA
    PNGs.

    Records that share a source image keep sharing one written file.
    """
    from olatbench.datasets.images import write_image

    out_dir = Path(out_dir)
    for split, frames in scene.frames.items():
        if not frames:
            continue
        if split not in SPLIT_FILES:
            raise DatasetError(
                f"split '{split}' has no SSS-GS file name; expected one of "
                f"{', '.join(SPLIT_FILES)}",
                path=scene.root,
            )
        written: dict[Path, str] = {}
        groups: list[list[tuple[Frame, str]]] = []
        for frame in frames:
            relative = written.get(frame.image_path) if frame.image_path is not None else None
            if relative is None:
                relative = f"{split}/{c.safe_file_stem(frame.frame_id)}"
                write_image(out_dir / f"{relative}{DEFAULT_EXT}", _encode(pixels(frame)), "uint8")
                if frame.image_path is not None:
                    written[frame.image_path] = relative
            if groups and _same_camera(groups[-1][0][0].camera, frame.camera):
                groups[-1].append((frame, relative))
            else:
                groups.append([(frame, relative)])
        entries = []
        for group in groups:
            camera = group[0][0].camera
            entry: dict[str, Any] = {
                "transform_matrix": opencv_to_opengl(camera.c2w).tolist(),
                "width": camera.width,
                "height": camera.height,
                "fl_x": camera.fx,
                "fl_y": camera.fy,
                "cx": camera.cx,
                "cy": camera.cy,
                "file_paths": [relative for _, relative in group],
                "light_positions": [
                    np.asarray(f.light.position, dtype=float).tolist() for f, _ in group
                ],
            }
            if all(f.light.intensity_known for f, _ in group):
                entry["light_intensities"] = [
                    np.asarray(f.light.intensity, dtype=float).tolist() for f, _ in group
                ]
            entries.append(entry)
        write_json(out_dir / SPLIT_FILES[split], {"frames": entries})
    return out_dir


def official_ground_truth(frame: Frame) -> np.ndarray:
    """sRGB colour times the alpha mask, composited on the frame's background (black), as the SSS-GS
    dataset class does."""
    rgb, alpha = c.stored_pixels(frame)
    return colour.composite(rgb, alpha, frame.background, "straight")
