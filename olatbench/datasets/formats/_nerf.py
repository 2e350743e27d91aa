"""Reader and writer of the NeRF-style ``transforms_<split>.json`` layout shared by NRHints and GS³.

One JSON file per split holds ``frames`` with ``file_path`` (no extension; ``file_ext`` per frame or
the format default) or ``img_path`` (relative to the scene folder, extension included; preferred
over ``file_path`` when a frame has both, as the GS³ loader ``scene/dataset_readers.py`` does; its
stem is then the frame id), ``transform_matrix`` (camera-to-world, OpenGL/Blender axes), ``pl_pos``
and optionally ``pl_intensity``. A frame with refined poses ``R_opt``/``T_opt`` gets its camera from
them, as the official readers do (`olatbench.datasets.cameras.c2w_from_refined`); its
``transform_matrix`` pose, when it has one, stays in ``extras["transform_matrix_c2w"]``, and a
written scene's ``transform_matrix`` is the refined camera, so every reader of it sees one camera.

The files GS³'s and SSD-GS's ``Scene.save`` write next to a trained model
(``point_cloud/iteration_N/transforms_ {train,test}.json``: ``file_path`` the image stem, an
absolute ``img_path``, ``R_opt``/``T_opt``, the refined ``pl_pos`` and per-frame
``camera_intrinsics``, no ``transform_matrix`` and no ``pl_intensity``) read as they are: an
absolute ``img_path`` is accepted when that file exists (``extras["absolute_img_path"]``, counted by
``datasets info``); a relative one still may not leave the folder.

Intrinsics are ``camera_intrinsics`` = **[cx, cy, fx, fy]** (top level or per frame) or
``camera_angle_x`` (square pixels, centred principal point), with each format's official reader's
precedence: at the top level the NRHints parser (``data/data_parser.py:54-66``) takes
``camera_intrinsics`` first, the GS³/SSD-GS reader (``scene/dataset_readers.py:105-113``)
``camera_angle_x`` (`NerfFlavour.angle_first`); a frame's own ``camera_intrinsics`` replace the top
level's (``dataset_readers.py:128-133``; NRHints reads none), except that under a top-level
``camera_angle_x`` the GS³/SSD-GS reader keeps that angle's focal length and takes only cx, cy from
the frame (``:168-174``, ``:187-193``). olatbench follows that for GS³ files; an NRHints file of
that shape whose frame focal differs from the angle's is refused (the two official readers disagree
on it). ``transforms_valid.json`` (the GS³ re-pack) is a camera path without images: split ``path``,
frames with ``image_path=None``.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.atomic import write_json
from olatbench.datasets import colour
from olatbench.datasets.cameras import (
    c2w_from_refined,
    fov_from_focal,
    intrinsics_from_fov,
    intrinsics_matrix,
    opencv_to_opengl,
)
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.formats import _common as c
from olatbench.datasets.records import Camera, Frame, PointLight, Scene

SPLIT_FILES: dict[str, str] = {
    "train": "transforms_train.json",
    "val": "transforms_val.json",
    "test": "transforms_test.json",
    "path": "transforms_valid.json",
}
IMAGE_SPLITS = ("train", "val", "test")


Background = tuple[float, float, float]


@dataclass(frozen=True)
class NerfFlavour:
    """What distinguishes NRHints from GS³ files: default extension, colour, alpha and
    background."""

    format_name: str
    default_ext: str
    colourspace: colour.ColourSpace
    alpha_mode: colour.AlphaMode
    background: Background
    # top-level camera_angle_x before camera_intrinsics (the GS³/SSD-GS reader)
    angle_first: bool = False
    # (root, {split: (file, meta)}) -> (background, why): a per-scene background instead of
    # ``background``
    background_rule: (
        Callable[[Path, Mapping[str, tuple[Path, dict]]], tuple[Background, str]] | None
    ) = None


def _intrinsics(
    source: Mapping[str, Any],
    width: int,
    height: int,
    *,
    path: Path,
    frame: str | int | None,
    angle_first: bool = False,
) -> np.ndarray | None:
    """K from ``camera_intrinsics`` [cx, cy, fx, fy] or ``camera_angle_x``
    (that one first with ``angle_first``); None when neither is in ``source``."""
    if angle_first and source.get("camera_angle_x") is not None:
        return _intrinsics(
            {"camera_angle_x": source["camera_angle_x"]}, width, height, path=path, frame=frame
        )
    if source.get("camera_intrinsics") is not None:
        cx, cy, fx, fy = c.as_array(
            source["camera_intrinsics"], (4,), path=path, frame=frame, key="camera_intrinsics"
        )
        if fx <= 0 or fy <= 0:
            raise DatasetError(
                f"focal lengths must be > 0, found fx={fx}, fy={fy}",
                path=path,
                frame=frame,
                key="camera_intrinsics",
            )
        return intrinsics_matrix(fx, fy, cx, cy)
    if source.get("camera_angle_x") is not None:
        fov = c.as_positive(source["camera_angle_x"], path=path, frame=frame, key="camera_angle_x")
        if fov >= np.pi:
            raise DatasetError(
                f"must be < π radians, found {fov}", path=path, frame=frame, key="camera_angle_x"
            )
        return intrinsics_from_fov(fov, width, height)
    return None


def _image_size(
    root: Path, metas: dict[str, tuple[Path, dict]], flavour: NerfFlavour
) -> tuple[int, int]:
    """(width, height): top-level ``w``/``h`` or the header of the first image of the first image
    split."""
    from olatbench.datasets.images import image_size

    for split in (*IMAGE_SPLITS, "path"):
        if split not in metas:
            continue
        path, meta = metas[split]
        if meta.get("w") is not None and meta.get("h") is not None:
            return (
                c.as_side(meta["w"], path=path, frame=None, key="w"),
                c.as_side(meta["h"], path=path, frame=None, key="h"),
            )
    for split in IMAGE_SPLITS:
        if split not in metas:
            continue
        path, meta = metas[split]
        frames = c.frames_of(meta, path)
        if frames:
            image = frame_image(root, frames[0], flavour.default_ext, path=path, frame=0)
            try:
                return image_size(image)
            except DatasetError as error:
                raise DatasetError(
                    f"{error.message} (needed for the image size)", path=image, frame=0
                ) from None
    raise DatasetError(
        "cannot determine the image size: no image split and no 'w'/'h' keys", path=root
    )


def frame_image(
    root: Path, raw: Mapping[str, Any], default_ext: str, *, path: Path, frame: str | int
) -> Path:
    """A frame's image: ``img_path`` as written (relative to ``root``, or absolute if that file
    exists, as ``Scene.save`` of GS³/SSD-GS writes it) when present, else ``file_path`` with
    ``file_ext`` or ``default_ext``."""
    img_path = raw.get("img_path")
    if isinstance(img_path, str) and os.path.isabs(img_path):
        if not Path(img_path).is_file():
            raise DatasetError(
                f"absolute image path '{img_path}' does not exist (an absolute img_path is read "
                "only where the file is)",
                path=path,
                frame=frame,
                key="img_path",
            )
        return Path(img_path)
    if img_path is not None:
        return c.resolve_inside(root, img_path, path=path, frame=frame, key="img_path")
    return c.image_file(
        root,
        c.require(raw, "file_path", path=path, frame=frame),
        raw.get("file_ext"),
        default_ext,
        path=path,
        frame=frame,
    )


def _frame_stem(raw: Mapping[str, Any], default: str) -> str:
    """The stem the frame id comes from: ``img_path``'s when present, else ``file_path``'s, else
    ``default``."""
    name = raw.get("img_path") if raw.get("img_path") is not None else raw.get("file_path", default)
    return Path(str(name)).stem


def _optional_positive(meta: Mapping[str, Any], key: str, path: Path) -> float | None:
    return (
        c.as_positive(meta[key], path=path, frame=None, key=key)
        if meta.get(key) is not None
        else None
    )


def read_nerf_scene(
    root: Path, flavour: NerfFlavour, name: str, errors: list[DatasetError] | None = None
) -> Scene:
    """Read every ``transforms_<split>.json`` of ``root``.

    With ``errors`` given, a bad frame is recorded there and skipped instead of raising.
    """
    root = Path(root)
    metas = {
        split: (path, c.read_json(path)) for split, path in c.split_files(root, SPLIT_FILES).items()
    }
    if not any(split in metas for split in IMAGE_SPLITS):
        raise DatasetError(f"no {', '.join(SPLIT_FILES[s] for s in IMAGE_SPLITS)}", path=root)
    width, height = _image_size(root, metas, flavour)
    background, why = flavour.background, None
    if flavour.background_rule is not None:
        background, why = flavour.background_rule(root, metas)
    background = np.asarray(background, dtype=np.float64)
    frames: dict[str, list[Frame]] = {}
    # train when present: the official parser's "meta"
    first_path, first_meta = next(iter(metas.values()))
    first = flavour.angle_first
    fallback = {
        "K": _intrinsics(first_meta, width, height, path=first_path, frame=None, angle_first=first),
        "near": _optional_positive(first_meta, "camera_near", first_path),
        "far": _optional_positive(first_meta, "camera_far", first_path),
    }
    for split, (path, meta) in metas.items():
        raw_frames = c.frames_of(meta, path)
        # a split without its own intrinsics / near / far uses the first split's, as the NRHints
        # parser does
        split_K = _intrinsics(meta, width, height, path=path, frame=None, angle_first=first)
        split_K = fallback["K"] if split_K is None else split_K
        angle_K = (
            _intrinsics(
                {"camera_angle_x": meta["camera_angle_x"]}, width, height, path=path, frame=None
            )
            if meta.get("camera_angle_x") is not None
            else None
        )
        near = _optional_positive(meta, "camera_near", path) or fallback["near"]
        far = _optional_positive(meta, "camera_far", path) or fallback["far"]
        stems = [
            _frame_stem(raw, f"{split}_{i:04d}") if split != "path" else f"path_{i:04d}"
            for i, raw in enumerate(raw_frames)
        ]
        parsed = []
        for index, (raw, frame_id) in enumerate(zip(raw_frames, c.unique_ids(stems), strict=True)):
            try:
                parsed.append(
                    _read_frame(
                        root,
                        path,
                        split,
                        index,
                        frame_id,
                        raw,
                        split_K,
                        angle_K,
                        width,
                        height,
                        near,
                        far,
                        name,
                        flavour,
                        background,
                    )
                )
            except DatasetError as error:
                if errors is None:
                    raise
                errors.append(error)
        frames[split] = parsed
    metadata = {"folder": root.name, "files": {s: p.name for s, (p, _) in metas.items()}}
    if why is not None:
        metadata["background"] = why
    return Scene(
        name=name,
        format=flavour.format_name,
        root=root,
        frames=frames,
        background=background,
        metadata=metadata,
    )


def _frame_K(
    raw: Mapping[str, Any],
    split_K: np.ndarray | None,
    angle_K: np.ndarray | None,
    width: int,
    height: int,
    flavour: NerfFlavour,
    where: dict[str, Any],
) -> np.ndarray | None:
    """A frame's K: its own ``camera_intrinsics``, with the focal length of the file's top-level
    ``camera_angle_x`` (``angle_K``) where there is one (GS³ reader; refused for NRHints files where
    it differs); else the split's K."""
    K = _intrinsics(raw, width, height, **where)
    if K is None:
        return split_K
    if angle_K is None or raw.get("camera_intrinsics") is None:
        return K
    if not flavour.angle_first and not np.allclose([K[0, 0], K[1, 1]], angle_K[0, 0], rtol=1e-6):
        raise DatasetError(
            f"fx={K[0, 0]:.6g}, fy={K[1, 1]:.6g} differ from the focal length {angle_K[0, 0]:.6g} "
            "px of the file's top-level camera_angle_x: NRHints' reader uses the angle and "
            "ignores per-frame intrinsics, GS³'s and SSD-GS's take the angle's focal length and "
            "this frame's cx, cy; remove one of the two",
            key="camera_intrinsics",
            **where,
        )
    K = K.copy()
    K[0, 0] = K[1, 1] = angle_K[0, 0]
    return K


def _read_frame(
    root: Path,
    path: Path,
    split: str,
    index: int,
    frame_id: str,
    raw: Mapping[str, Any],
    split_K: np.ndarray | None,
    angle_K: np.ndarray | None,
    width: int,
    height: int,
    near: float | None,
    far: float | None,
    name: str,
    flavour: NerfFlavour,
    background: np.ndarray,
) -> Frame:
    where = {"path": path, "frame": frame_id}
    refined = raw.get("R_opt") is not None or raw.get("T_opt") is not None
    # Scene.save of GS³/SSD-GS writes the refined pose only: transform_matrix is needed only without
    # it
    c2w = (
        c.opencv_c2w(c.require(raw, "transform_matrix", **where), **where)
        if not refined or raw.get("transform_matrix") is not None
        else None
    )
    K = _frame_K(raw, split_K, angle_K, width, height, flavour, where)
    if K is None:
        raise DatasetError(
            "no intrinsics: expected 'camera_intrinsics' or 'camera_angle_x'", **where
        )
    position = c.as_array(c.require(raw, "pl_pos", **where), (3,), key="pl_pos", **where)
    intensity_known = raw.get("pl_intensity") is not None
    intensity = (
        c.as_rgb(raw["pl_intensity"], key="pl_intensity", **where)
        if intensity_known
        else np.ones(3)
    )
    image_path = None
    if split != "path":
        image_path = frame_image(root, raw, flavour.default_ext, **where)
    extras: dict[str, Any] = {}
    if image_path is not None and os.path.isabs(str(raw.get("img_path", ""))):
        extras["absolute_img_path"] = str(image_path)
    if refined:
        # refined pose: the official GS³/SSD-GS readers use it instead of transform_matrix
        # (dataset_readers.py: 135-148), so the camera is the refined one; transform_matrix's pose
        # is kept aside
        extras["R_opt"] = c.as_array(c.require(raw, "R_opt", **where), (3, 3), key="R_opt", **where)
        extras["T_opt"] = c.as_array(c.require(raw, "T_opt", **where), (3,), key="T_opt", **where)
        rotation = extras["R_opt"]
        if (
            not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-4)
            or np.linalg.det(rotation) <= 0
        ):
            raise DatasetError("R_opt is not a rotation matrix", key="R_opt", **where)
        if c2w is not None:
            extras["transform_matrix_c2w"] = c2w
        c2w = c2w_from_refined(extras["R_opt"], extras["T_opt"])
    if split == "path" and raw.get("file_path") is not None:
        extras["file_path"] = str(raw["file_path"])
    camera = Camera(K=K, c2w=c2w, width=width, height=height, near=near, far=far)
    return Frame(
        scene=name,
        split=split,
        frame_id=frame_id,
        image_path=image_path,
        camera=camera,
        light=PointLight(position=position, intensity=intensity, intensity_known=intensity_known),
        colourspace=flavour.colourspace,
        alpha_mode=flavour.alpha_mode,
        background=background.copy(),
        extras=extras,
    )


def _shared_intrinsics(frames: list[Frame]) -> np.ndarray | None:
    """The K every frame shares, else None."""
    if frames and all(np.allclose(f.camera.K, frames[0].camera.K) for f in frames):
        return frames[0].camera.K
    return None


def _intrinsics_json(K: np.ndarray, width: int, height: int) -> dict[str, Any]:
    """``camera_angle_x`` for square pixels and a centred principal point, else
    ``camera_intrinsics``."""
    fx, fy, cx, cy = float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])
    if np.isclose(fx, fy) and np.isclose(cx, width / 2) and np.isclose(cy, height / 2):
        return {"camera_angle_x": fov_from_focal(fx, width)}
    return {"camera_intrinsics": [cx, cy, fx, fy]}


def write_nerf_scene(
    scene: Scene,
    out_dir: Path,
    flavour: NerfFlavour,
    encode: Callable[[np.ndarray], np.ndarray],
    pixels: Callable[[Frame], np.ndarray],
    bit_depth: str,
) -> Path:
    """Write ``scene`` as ``transforms_<split>.json`` + ``<split>/<frame_id><ext>``.

    ``encode`` turns linear straight RGBA (H, W, 4) into what the files hold.
    """
    from olatbench.datasets.images import write_image

    out_dir = Path(out_dir)
    for split, frames in scene.frames.items():
        if not frames:
            continue
        file = SPLIT_FILES.get(split)
        if file is None:
            raise DatasetError(
                f"split '{split}' has no {flavour.format_name} file name; "
                f"expected one of {', '.join(SPLIT_FILES)}",
                path=scene.root,
            )
        first = frames[0].camera
        K = _shared_intrinsics(frames)
        meta: dict[str, Any] = (
            _intrinsics_json(K, first.width, first.height) if K is not None else {}
        )
        if first.near is not None:
            meta["camera_near"] = first.near
        if first.far is not None:
            meta["camera_far"] = first.far
        meta["frames"] = []
        for frame in frames:
            stem = c.safe_file_stem(frame.frame_id)
            entry: dict[str, Any] = {"file_path": f"./{split}/{stem}"}
            if split != "path":
                write_image(
                    out_dir / split / f"{stem}{flavour.default_ext}",
                    encode(pixels(frame)),
                    bit_depth,
                )
                entry["file_ext"] = flavour.default_ext
            entry["transform_matrix"] = opencv_to_opengl(frame.camera.c2w).tolist()
            if K is None:
                entry["camera_intrinsics"] = [
                    frame.camera.cx,
                    frame.camera.cy,
                    frame.camera.fx,
                    frame.camera.fy,
                ]
            entry["pl_pos"] = np.asarray(frame.light.position, dtype=float).tolist()
            if frame.light.intensity_known:
                entry["pl_intensity"] = np.asarray(frame.light.intensity, dtype=float).tolist()
            for key in ("R_opt", "T_opt"):
                if key in frame.extras:
                    entry[key] = np.asarray(frame.extras[key], dtype=float).tolist()
            meta["frames"].append(entry)
        write_json(out_dir / file, meta)
    return out_dir
