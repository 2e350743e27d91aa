"""Write tiny dataset trees in each official format, for tests (of any part of olatbench).

The JSON is written here by hand, independently of `olatbench.datasets.convert`, so that reader
tests do not merely mirror the writers. Every function returns a `Tree` with what was written: per
split a list of dicts with ``c2w_gl`` (4×4 OpenGL axes, as in the file), ``K`` (3×3), ``pl_pos``
(3,), ``pl_intensity`` ((3,) or None), ``file`` (Path or None) and ``stored`` (the pixel values as
written: float (H, W, 4) in the file's encoding and alpha mode).

>>> tree = write_nrhints_tree(tmp_path / "Cat", n_train=4, n_test=2, size=(16, 12))
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.datasets.images import read_image, write_image


@dataclass
class Tree:
    """What a tree writer wrote."""

    root: Path
    frames: dict[str, list[dict[str, Any]]] = field(default_factory=dict)


def gl_look_at(eye, target=(0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Camera-to-world in OpenGL/Blender axes (x right, y up, camera looks down −z)."""
    eye, target, up = (np.asarray(v, dtype=np.float64) for v in (eye, target, up))
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    c2w = np.eye(4)
    c2w[:3, 0], c2w[:3, 1], c2w[:3, 2], c2w[:3, 3] = right, true_up, -forward, eye
    return c2w


def _eyes(n: int, radius: float, rng: np.random.Generator) -> np.ndarray:
    """``n`` points on a sphere, away from the poles (so that world z can serve as ``up``)."""
    azimuth = rng.uniform(0, 2 * np.pi, n)
    elevation = rng.uniform(-0.8, 0.8, n)
    return radius * np.stack(
        [
            np.cos(elevation) * np.cos(azimuth),
            np.cos(elevation) * np.sin(azimuth),
            np.sin(elevation),
        ],
        axis=1,
    )


def rgba_pattern(width: int, height: int, rng: np.random.Generator) -> np.ndarray:
    """Straight RGBA in [0, 1]: alpha 0 on a border, 1 inside, a fractional ramp on one row band."""
    rgba = rng.uniform(0.0, 1.0, (height, width, 4)).astype(np.float32)
    alpha = np.ones((height, width), dtype=np.float32)
    alpha[:, :2] = 0.0
    alpha[: max(1, height // 4), :] = np.linspace(0.0, 1.0, width, dtype=np.float32)
    rgba[..., 3] = alpha
    return rgba


def _quantised(x: np.ndarray) -> np.ndarray:
    return np.rint(np.clip(x, 0, 1) * 255.0) / 255.0


def write_nrhints_tree(
    root: Path,
    n_train: int = 4,
    n_test: int = 2,
    size: tuple[int, int] = (16, 12),
    *,
    n_val: int = 0,
    n_path: int = 0,
    intrinsics: bool = True,
    intensity: bool = True,
    seed: int = 0,
) -> Tree:
    """An NRHints scene: ``camera_intrinsics`` [cx, cy, fx, fy] (or ``camera_angle_x`` when
    ``intrinsics=False``), ``file_path`` without extension, 8-bit sRGB straight RGBA PNGs.
    ``n_path`` > 0 also writes ``transforms_valid.json`` (a camera path without images)."""
    rng = np.random.default_rng(seed)
    root = Path(root)
    width, height = size
    cx, cy, fx, fy = width / 2 + 0.75, height / 2 - 0.5, 1.2 * width, 1.1 * width
    K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
    fov_x = 2 * np.arctan(0.5 * width / (1.2 * width))
    tree = Tree(root)
    for split, n, json_name in (
        ("train", n_train, "transforms_train.json"),
        ("val", n_val, "transforms_val.json"),
        ("test", n_test, "transforms_test.json"),
        ("path", n_path, "transforms_valid.json"),
    ):
        if n == 0:
            continue
        meta: dict[str, Any] = (
            {"camera_intrinsics": [cx, cy, fx, fy]} if intrinsics else {"camera_angle_x": fov_x}
        )
        meta["frames"] = []
        records = []
        for i, (eye, light) in enumerate(zip(_eyes(n, 4.0, rng), _eyes(n, 6.0, rng), strict=True)):
            c2w = gl_look_at(eye)
            entry: dict[str, Any] = {
                "file_path": f"./{split}/{i:03d}",
                "transform_matrix": c2w.tolist(),
                "pl_pos": light.tolist(),
            }
            pl_intensity = None
            if intensity:
                pl_intensity = np.array([30.0, 28.0, 26.0]) + i
                entry["pl_intensity"] = pl_intensity.tolist()
            file, stored = None, None
            if split != "path":
                stored = _quantised(rgba_pattern(width, height, rng))
                file = root / split / f"{i:03d}.png"
                write_image(file, stored, "uint8")
            meta["frames"].append(entry)
            if not intrinsics:
                focal = 0.5 * width / np.tan(0.5 * fov_x)
                K = np.array([[focal, 0, width / 2], [0, focal, height / 2], [0, 0, 1.0]])
            records.append(
                {
                    "c2w_gl": c2w,
                    "K": K.copy(),
                    "pl_pos": light,
                    "pl_intensity": pl_intensity,
                    "file": file,
                    "stored": stored,
                }
            )
        root.mkdir(parents=True, exist_ok=True)
        (root / json_name).write_text(json.dumps(meta, indent=1))
        tree.frames[split] = records
    return tree


def write_gs3_tree(
    root: Path,
    n_train: int = 4,
    n_test: int = 2,
    size: tuple[int, int] = (16, 12),
    *,
    n_path: int = 0,
    with_opt: bool = True,
    seed: int = 0,
) -> Tree:
    """A GS³ scene: ``camera_angle_x``, ``camera_near``/``camera_far``, per-frame ``file_ext``
    ".exr", ``pl_intensity``, half-float linear premultiplied RGBA EXRs (HDR values up to 4), and
    ``R_opt``/``T_opt`` on the first train frame when ``with_opt``."""
    rng = np.random.default_rng(seed)
    root = Path(root)
    width, height = size
    fov_x = 0.69
    focal = 0.5 * width / np.tan(0.5 * fov_x)
    K = np.array([[focal, 0, width / 2], [0, focal, height / 2], [0, 0, 1.0]])
    tree = Tree(root)
    for split, n, json_name in (
        ("train", n_train, "transforms_train.json"),
        ("test", n_test, "transforms_test.json"),
        ("path", n_path, "transforms_valid.json"),
    ):
        if n == 0:
            continue
        meta: dict[str, Any] = {
            "camera_angle_x": fov_x,
            "camera_near": 0.5,
            "camera_far": 20.0,
            "frames": [],
        }
        records = []
        for i, (eye, light) in enumerate(zip(_eyes(n, 4.0, rng), _eyes(n, 5.0, rng), strict=True)):
            c2w = gl_look_at(eye)
            pl_intensity = np.array([40.0, 40.0, 40.0])
            entry: dict[str, Any] = {
                "file_path": f"{split}/r_{i}",
                "file_ext": ".exr",
                "transform_matrix": c2w.tolist(),
                "pl_pos": light.tolist(),
                "pl_intensity": pl_intensity.tolist(),
            }
            if with_opt and split == "train" and i == 0:
                entry["R_opt"] = np.eye(3).tolist()
                entry["T_opt"] = [0.1, 0.2, 0.3]
            file, stored = None, None
            if split != "path":
                straight = rgba_pattern(width, height, rng)
                straight[..., :3] *= 4.0  # HDR
                stored = straight.copy()
                stored[..., :3] *= straight[..., 3:4]  # premultiplied
                stored = stored.astype(np.float16).astype(np.float32)
                file = root / split / f"r_{i}.exr"
                write_image(file, stored, "half")
            meta["frames"].append(entry)
            records.append(
                {
                    "c2w_gl": c2w,
                    "K": K.copy(),
                    "pl_pos": light,
                    "pl_intensity": pl_intensity,
                    "file": file,
                    "stored": stored,
                }
            )
        root.mkdir(parents=True, exist_ok=True)
        (root / json_name).write_text(json.dumps(meta, indent=1))
        tree.frames[split] = records
    return tree


def write_sssgs_tree(
    root: Path,
    n_train_cameras: int = 2,
    n_test_cameras: int = 1,
    lights_per_camera: int = 3,
    size: tuple[int, int] = (16, 16),
    *,
    excluded: tuple[str, ...] = (),
    share_first: bool = False,
    seed: int = 0,
) -> Tree:
    """An SSS-GS scene: camera frames with ``file_paths``/``light_positions`` lists, per-frame
    ``width``, ``height``, ``fl_x``, ``fl_y``, ``cx``, ``cy``, 8-bit sRGB RGBA PNGs,
    ``exclude_list.txt`` listing ``excluded`` (names like ``"r_0_l_1.png"``; those records are left
    out of ``Tree.frames``). ``share_first``: the first two lights of the first train camera
    reference the same PNG."""
    rng = np.random.default_rng(seed)
    root = Path(root)
    width, height = size
    fl_x, fl_y, cx, cy = 1.3 * width, 1.25 * width, width / 2 - 0.25, height / 2 + 0.5
    K = np.array([[fl_x, 0, cx], [0, fl_y, cy], [0, 0, 1.0]])
    excluded_stems = {name.replace(".png", "") for name in excluded}
    tree = Tree(root)
    root.mkdir(parents=True, exist_ok=True)
    if excluded:
        (root / "exclude_list.txt").write_text("\n".join(excluded) + "\n")
    for split, n, json_name in (
        ("train", n_train_cameras, "transforms_train.json"),
        ("test", n_test_cameras, "transforms_test.json"),
    ):
        frames, records = [], []
        for c_index, eye in enumerate(_eyes(n, 3.5, rng)):
            c2w = gl_look_at(eye)
            lights = _eyes(lights_per_camera, 5.0, rng)
            paths = []
            for l_index in range(lights_per_camera):
                stem = f"{split}/r_{c_index}_l_{l_index}"
                if share_first and split == "train" and c_index == 0 and l_index == 1:
                    stem = f"{split}/r_0_l_0"
                else:
                    stored = _quantised(rgba_pattern(width, height, rng))
                    write_image(root / f"{stem}.png", stored, "uint8")
                paths.append(stem)
                if stem.split("/")[-1] in excluded_stems:
                    continue
                records.append(
                    {
                        "c2w_gl": c2w,
                        "K": K.copy(),
                        "pl_pos": lights[l_index],
                        "pl_intensity": None,
                        "file": root / f"{stem}.png",
                        "stored": None,
                    }
                )
            frames.append(
                {
                    "transform_matrix": c2w.tolist(),
                    "width": width,
                    "height": height,
                    "fl_x": fl_x,
                    "fl_y": fl_y,
                    "cx": cx,
                    "cy": cy,
                    "file_paths": paths,
                    "light_positions": lights.tolist(),
                }
            )
        (root / json_name).write_text(json.dumps({"frames": frames}, indent=1))
        for record in records:
            record["stored"] = read_image(record["file"])
        tree.frames[split] = records
    return tree
