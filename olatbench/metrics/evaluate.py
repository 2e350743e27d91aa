"""Score a folder of rendered images against a scene's ground truth under one protocol.

Predictions are matched to ground-truth frames by file stem = frame id
(``renders/<split>/<frame_id>.png``, the runner's layout). Missing, ambiguous (two files for one id)
and unknown (extra) files are refused with the full list; unreadable files are named. The result
holds per-image values, the protocol's id, version and definition, and the sha256 of every file
scored; ``olatbench evaluate`` writes it as a results.json of schema version 2 with the runner's
provenance (`olatbench.bench.evaluate`).
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from olatbench.datasets import colour
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.formats import display_colourspace
from olatbench.metrics.protocols import Protocol

IMAGE_SUFFIXES = (".png", ".exr", ".jpg", ".jpeg", ".tif", ".tiff", ".hdr")
LINEAR_SUFFIXES = (".exr", ".hdr")
# The space the official pipelines train and score in (see olatbench.datasets.official): protocols
# with ground_truth="official" score in it.


class EvaluationError(ValueError):
    """Predictions that cannot be scored: the message lists every offending file or frame."""


def _listing(title: str, items: Sequence[str], limit: int = 20) -> str:
    shown = ", ".join(items[:limit]) + (
        f", … ({len(items) - limit} more)" if len(items) > limit else ""
    )
    return f"{title} ({len(items)}): {shown}"


def match_predictions(
    pred_dir: Path, frame_ids: Sequence[str], allow_extra: bool = False
) -> dict[str, Path]:
    """frame id -> prediction file in ``pred_dir`` (stem = frame id, image suffixes only).

    Raises `EvaluationError` listing missing ids, ambiguous ids and (unless ``allow_extra``) extra
    files.
    """
    pred_dir = Path(pred_dir)
    if not pred_dir.is_dir():
        raise EvaluationError(f"prediction folder {pred_dir} does not exist")
    wanted = set(frame_ids)
    found: dict[str, list[Path]] = {}
    for path in sorted(pred_dir.iterdir()):
        if (
            path.is_file()
            and not path.name.startswith(".")
            and path.suffix.lower() in IMAGE_SUFFIXES
        ):
            found.setdefault(path.stem, []).append(path)
    problems = []
    missing = [i for i in frame_ids if i not in found]
    ambiguous = [
        f"{i} ({', '.join(p.name for p in found[i])})"
        for i in frame_ids
        if len(found.get(i, [])) > 1
    ]
    extra = [p.name for stem, paths in found.items() if stem not in wanted for p in paths]
    if missing:
        problems.append(_listing("missing predictions for frames", missing))
    if ambiguous:
        problems.append(_listing("several files for one frame", ambiguous))
    if extra and not allow_extra:
        problems.append(
            _listing("files matching no ground-truth frame", extra)
            + " (use --allow-extra to skip them)"
        )
    if problems:
        raise EvaluationError(
            f"{pred_dir}: cannot match predictions to {len(frame_ids)} frames:\n  "
            + "\n  ".join(problems)
        )
    return {i: found[i][0] for i in frame_ids}


def read_prediction(
    path: Path, colourspace: str, background: np.ndarray, encoded_as: str = "srgb"
) -> np.ndarray:
    """A prediction file as float32 (H, W, 3) in ``colourspace``.

    PNG/JPEG/TIFF hold values encoded as ``encoded_as`` (sRGB by default), EXR/HDR linear light.
    RGBA is composited (straight alpha) over ``background`` (given in ``colourspace``).
    """
    from olatbench.datasets.images import read_image

    pixels = read_image(path)
    channels = pixels.shape[2]
    if channels not in (3, 4):
        raise DatasetError(f"expected an RGB or RGBA image, found {channels} channels", path=path)
    if not np.isfinite(pixels).all():
        raise DatasetError("image holds NaN or Inf pixels", path=path)
    stored = "linear" if path.suffix.lower() in LINEAR_SUFFIXES else encoded_as
    rgb = colour.convert_colourspace(pixels[..., :3], stored, colourspace)
    if channels == 4:
        rgb = colour.composite(rgb, pixels[..., 3], background, "straight")
    return rgb.astype(np.float32)


def sha256_file(path: Path) -> str:
    """Hex sha256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def evaluate_matched(
    protocol: Protocol,
    matched: Mapping[str, Path],
    ground_truth: Callable[[str], tuple[np.ndarray, np.ndarray | None, Path | None]],
    background: np.ndarray,
    progress: bool = False,
    batch_size: int = 4,
    colourspace: str = "srgb",
    png_space: str = "srgb",
) -> tuple[dict[str, dict], dict[str, dict]]:
    """Score predictions given as frame id -> file against ``ground_truth(frame_id) -> (rgb, mask,
    file)``.

    ``colourspace``: the space predictions are scored in (the data's display space); ``png_space``:
    how 8-bit prediction files are encoded (``srgb``: the runner's renders). Returns (per_image
    metrics by frame id, the files scored by frame id: ``{"render", "render_sha256", "ground_truth",
    "ground_truth_sha256"}``, the results.json ``files`` entries).
    """
    space = colourspace
    ids = list(matched)
    inputs: dict[str, dict] = {}

    def pairs():
        for frame_id in ids:
            path = matched[frame_id]
            try:
                pred = read_prediction(path, space, background, encoded_as=png_space)
                gt, mask, gt_path = ground_truth(frame_id)
            except DatasetError as error:
                raise EvaluationError(f"frame {frame_id}: {error}") from None
            if pred.shape != gt.shape:
                raise EvaluationError(
                    f"frame {frame_id}: prediction {path.name} is {pred.shape[1]}×{pred.shape[0]} "
                    f"but the ground truth is {gt.shape[1]}×{gt.shape[0]} (use --resize-gt to "
                    "score against an area-resized ground truth)"
                )
            inputs[frame_id] = {
                "render": str(path),
                "render_sha256": sha256_file(path),
                "ground_truth": None if gt_path is None else str(gt_path),
                "ground_truth_sha256": None if gt_path is None else sha256_file(gt_path),
            }
            yield pred, gt, mask

    rows = protocol.evaluate_many(pairs(), progress=progress, batch_size=batch_size, total=len(ids))
    return dict(zip(ids, rows, strict=True)), inputs


def evaluate_folder(
    pred_dir: str | Path,
    scene_dir: str | Path,
    split: str = "test",
    protocol: Protocol | None = None,
    allow_extra: bool = False,
    resize_gt: bool = False,
    progress: bool = False,
    png_space: str = "srgb",
) -> dict:
    """Score ``pred_dir`` against split ``split`` of the scene at ``scene_dir``.

    Returns ``{"protocol": {"id", "version", "definition"}, "source": {"predictions", "scene",
    "split", "colourspace", "png_space"}, "metrics": {split: {"mean", "per_image"}}, "files":
    {split: {frame id: ...}}}``: the blocks of a results.json that scoring decides
    (`olatbench.bench.evaluate` adds the rest).

    ``png_space``: encoding of 8-bit prediction files (``srgb`` for olatbench renders; ``gamma22``
    for renders saved by the official GS³/SSD-GS scripts of GS³ data).
    """
    if png_space not in colour.COLOUR_SPACES:
        raise EvaluationError(
            f"unknown png_space {png_space!r}; expected one of {colour.COLOUR_SPACES}"
        )
    from olatbench.datasets import load_scene
    from olatbench.metrics.protocols import get_protocol

    protocol = protocol or get_protocol("olatbench-v1")
    scene = load_scene(scene_dir)
    frames = {f.frame_id: f for f in scene.split(split) if f.image_path is not None}
    if not frames:
        raise EvaluationError(f"{scene_dir}: split '{split}' has no ground-truth images")
    matched = match_predictions(Path(pred_dir), list(frames), allow_extra)
    space = display_colourspace(scene.format)
    background = colour.convert_colourspace(
        np.asarray(scene.background, np.float32), next(iter(frames.values())).colourspace, space
    )

    def ground_truth(frame_id: str):
        frame = frames[frame_id]
        resolution = None
        if resize_gt:
            from olatbench.datasets.images import image_size

            resolution = image_size(matched[frame_id])
        rgb, mask = protocol.load_ground_truth(frame, scene.format, resolution)
        return rgb, mask, frame.image_path

    per_image, inputs = evaluate_matched(
        protocol,
        matched,
        ground_truth,
        background,
        progress,
        colourspace=space,
        png_space=png_space,
    )
    return {
        "protocol": {
            "id": protocol.id,
            "version": protocol.version,
            "definition": protocol.definition(),
        },
        "source": {
            "predictions": str(Path(pred_dir).resolve()),
            "scene": {
                "name": scene.name,
                "format": scene.format,
                "root": str(Path(scene_dir).resolve()),
            },
            "split": split,
            "colourspace": space,
            "png_space": png_space,
        },
        "metrics": {
            split: {"mean": protocol.mean(list(per_image.values())), "per_image": per_image}
        },
        "files": {split: inputs},
    }
