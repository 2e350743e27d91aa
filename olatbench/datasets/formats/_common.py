"""Parsing helpers shared by the format readers: JSON, keys, numbers and paths.

Every failure is one `DatasetError` naming the file, the frame and the key. Paths
read from a JSON file are resolved and must stay inside the dataset root.
"""

from __future__ import annotations

import os
import re
from collections import Counter
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.datasets.cameras import opengl_to_opencv
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.files import present, require_file
from olatbench.datasets.images import read_image
from olatbench.datasets.jsontext import parse_json
from olatbench.datasets.records import Frame
from olatbench.datasets.sizes import checked_side

# |coordinate| bound: squared distances of such values stay finite in float32 (3.4e38)
MAX_MAGNITUDE = 1e18
IMAGE_SUFFIXES = (".png", ".exr", ".jpg", ".jpeg", ".tif", ".tiff", ".hdr", ".npy")


def read_json(path: Path) -> dict[str, Any]:
    """Parse a JSON object; missing, unreadable or malformed files (a folder, a link loop) raise
    `DatasetError`."""
    require_file(path, "JSON file")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise DatasetError(f"cannot read ({error})", path=path) from None
    try:
        data = parse_json(text)
    except ValueError as error:
        raise DatasetError(str(error), path=path) from None
    if not isinstance(data, dict):
        raise DatasetError("expected a JSON object at the top level", path=path)
    return data


def frames_of(meta: Mapping[str, Any], path: Path) -> list[Mapping[str, Any]]:
    """The ``frames`` list of a transforms file, each entry a JSON object."""
    frames = require(meta, "frames", path=path)
    if not isinstance(frames, list):
        raise DatasetError("expected a list", path=path, key="frames")
    if not frames:
        raise DatasetError("empty list: the file describes no frame", path=path, key="frames")
    for index, frame in enumerate(frames):
        if not isinstance(frame, dict):
            raise DatasetError("expected a JSON object", path=path, frame=index, key="frames")
    return frames


def require(
    mapping: Mapping[str, Any], key: str, *, path: Path, frame: str | int | None = None
) -> Any:
    """``mapping[key]`` or a `DatasetError` naming the missing key."""
    if key not in mapping or mapping[key] is None:
        raise DatasetError("missing key", path=path, frame=frame, key=key)
    return mapping[key]


def as_array(
    value: Any, shape: tuple[int, ...], *, path: Path, frame: str | int | None, key: str
) -> np.ndarray:
    """A finite float64 array of exactly ``shape``, every value of magnitude at most
    `MAX_MAGNITUDE`."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise DatasetError(
            f"expected numbers of shape {shape}", path=path, frame=frame, key=key
        ) from None
    if array.shape != shape:
        raise DatasetError(
            f"expected shape {shape}, found {array.shape}", path=path, frame=frame, key=key
        )
    if not np.all(np.isfinite(array)):
        raise DatasetError("holds NaN or Inf", path=path, frame=frame, key=key)
    if np.any(np.abs(array) > MAX_MAGNITUDE):
        raise DatasetError(
            f"holds a value of magnitude above {MAX_MAGNITUDE:.0e} ({np.abs(array).max():.3g}); "
            "the renderers square distances in 32-bit floats",
            path=path,
            frame=frame,
            key=key,
        )
    return array


def as_positive(value: Any, *, path: Path, frame: str | int | None, key: str) -> float:
    """A finite number > 0."""
    number = float(as_array(value, (), path=path, frame=frame, key=key))
    if number <= 0.0:
        raise DatasetError(f"must be > 0, found {number}", path=path, frame=frame, key=key)
    return number


def as_side(value: Any, *, path: Path, frame: str | int | None, key: str) -> int:
    """An image side in pixels (`olatbench.datasets.sizes.checked_side`: whole, 1 to its bound)."""
    try:
        return checked_side(value)
    except ValueError as error:
        raise DatasetError(str(error), path=path, frame=frame, key=key) from None


def as_rgb(value: Any, *, path: Path, frame: str | int | None, key: str) -> np.ndarray:
    """An RGB triple from a scalar or a 3-list (finite, ≥ 0)."""
    array = np.asarray(value, dtype=object)
    rgb = as_array(
        value, array.shape if array.shape in ((), (1,)) else (3,), path=path, frame=frame, key=key
    )
    rgb = np.broadcast_to(rgb.reshape(-1), (3,)).astype(np.float64)
    if np.any(rgb < 0):
        raise DatasetError("must be ≥ 0", path=path, frame=frame, key=key)
    return rgb


def opencv_c2w(
    value: Any, *, path: Path, frame: str | int | None, key: str = "transform_matrix"
) -> np.ndarray:
    """A JSON camera-to-world matrix (OpenGL/Blender axes, 4×4 or 3×4) converted once to OpenCV
    axes."""
    array = np.asarray(value, dtype=object)
    shape = (3, 4) if array.shape == (3, 4) else (4, 4)
    c2w = as_array(value, shape, path=path, frame=frame, key=key)
    if shape == (4, 4) and not np.allclose(c2w[3], [0.0, 0.0, 0.0, 1.0]):
        raise DatasetError(
            f"last row must be [0, 0, 0, 1], found {c2w[3].tolist()}",
            path=path,
            frame=frame,
            key=key,
        )
    determinant = float(np.linalg.det(c2w[:3, :3]))
    if determinant <= 0.0:
        raise DatasetError(
            f"the rotation is a reflection or singular (determinant {determinant:.3g}, expected "
            "+1); a mirrored camera renders every image flipped",
            path=path,
            frame=frame,
            key=key,
        )
    return opengl_to_opencv(c2w)


def resolve_inside(
    root: Path, relative: Any, *, path: Path, frame: str | int | None, key: str
) -> Path:
    """A path read from JSON, joined to ``root``; refuse one that, as written, leaves the root
    (absolute, or more ``..`` than folders). Symbolic links on disk are not judged: a folder the
    user linked elsewhere (``train/`` on another disk) is theirs to make, and an archive olatbench
    unpacks holds no links."""
    if not isinstance(relative, str) or not relative.strip():
        raise DatasetError("expected a non-empty relative path", path=path, frame=frame, key=key)
    base = root.resolve()
    normal = os.path.normpath(relative)
    if os.path.isabs(normal) or normal == ".." or normal.startswith(".." + os.sep):
        raise DatasetError(
            f"path '{relative}' leaves the dataset root {base}", path=path, frame=frame, key=key
        )
    return base / normal


def image_file(
    root: Path,
    file_path: Any,
    ext: Any,
    default_ext: str,
    *,
    path: Path,
    frame: str | int | None,
    key: str = "file_path",
) -> Path:
    """The image of a ``file_path`` (stored without extension) plus ``ext`` (``file_ext``) or
    ``default_ext``.

    Without ``file_ext``, a ``file_path`` that already ends in an image suffix is used as is.
    """
    if not isinstance(file_path, str):
        raise DatasetError("expected a non-empty relative path", path=path, frame=frame, key=key)
    if ext is None:
        if Path(file_path).suffix.lower() in IMAGE_SUFFIXES:
            return resolve_inside(root, file_path, path=path, frame=frame, key=key)
        ext = default_ext
    if not isinstance(ext, str):
        raise DatasetError(
            "expected a string such as '.png'", path=path, frame=frame, key="file_ext"
        )
    suffix = ext if not ext or ext.startswith(".") else "." + ext
    return resolve_inside(root, f"{file_path}{suffix}", path=path, frame=frame, key=key)


def unique_ids(stems: list[str]) -> list[str]:
    """Make frame ids unique within a split: repeated stems get ``-<occurrence>`` suffixes."""
    counts = Counter(stems)
    seen: Counter[str] = Counter()
    ids = []
    for stem in stems:
        if counts[stem] > 1:
            seen[stem] += 1
            ids.append(f"{stem}-{seen[stem]}")
        else:
            ids.append(stem)
    return ids


def safe_file_stem(frame_id: str) -> str:
    """A file name stem for a frame id (path separators and unusual characters become ``_``)."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", frame_id).lstrip(".") or "frame"


def split_files(root: Path, names: Mapping[str, str]) -> dict[str, Path]:
    """{split: path} of the transforms files present in ``root`` (``names``: split -> file name).
    Anything at a file's name counts, so a folder or a link loop there becomes an error when read,
    never a silently missing split."""
    return {split: root / name for split, name in names.items() if present(root / name)}


def first_frame(
    root: Path, names: tuple[str, ...]
) -> tuple[Path, dict[str, Any], Mapping[str, Any]] | None:
    """(file, meta, first frame) of the first existing transforms file among ``names``
    (for detection)."""
    for name in names:
        path = root / name
        if path.is_file():
            meta = read_json(path)
            frames = frames_of(meta, path)
            if frames:
                return path, meta, frames[0]
    return None


def stored_pixels(frame: Frame) -> tuple[np.ndarray, np.ndarray]:
    """The file's colour (as stored, premultiplied if the format is) and alpha (1 when absent)."""
    if frame.image_path is None:
        raise DatasetError("this frame has no image (a camera path)", frame=frame.frame_id)
    pixels = read_image(frame.image_path)
    if pixels.shape[:2] != (frame.camera.height, frame.camera.width):
        raise DatasetError(
            f"image is {pixels.shape[1]}×{pixels.shape[0]} but the camera says "
            f"{frame.camera.width}×{frame.camera.height}",
            path=frame.image_path,
            frame=frame.frame_id,
        )
    rgb = np.repeat(pixels, 3, axis=2) if pixels.shape[2] == 1 else pixels[..., :3]
    alpha = pixels[..., 3] if pixels.shape[2] == 4 else np.ones(pixels.shape[:2], dtype=np.float32)
    return rgb, alpha
