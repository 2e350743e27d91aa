"""NRHints (Zeng et al. 2023) OLAT scenes, real and synthetic, and the GS³ re-pack of the real ones.

Files: ``transforms_{train,val,test}.json`` (+ ``transforms_valid.json``: a camera path without
images, exposed as split ``path``). Intrinsics ``camera_intrinsics`` = [cx, cy, fx, fy] with a
``camera_angle_x`` fallback. Images: RGBA PNG, sRGB, straight alpha.

Background, per scene (`scene_background`; ``datasets info`` prints the reason): NRHints trains its
real captures on black (``scripts/train_real.sh``: ``--config.data.white-background False``) and its
synthetic Blender scenes on white (``scripts/train_synthetic.sh``: ``True``;
``data/data_parser.py:100-103``). A synthetic scene is one whose transforms files give
``camera_angle_x`` and no ``camera_intrinsics`` (the Blender export; every real capture has
calibrated ``camera_intrinsics``). Scenes made by olatbench's generator (a ``synth.json`` beside the
files, e.g. the ``mini`` suite) keep black, the empty background they were rendered with.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.datasets import colour
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.formats import _common as c
from olatbench.datasets.formats._nerf import (
    SPLIT_FILES,
    NerfFlavour,
    read_nerf_scene,
    write_nerf_scene,
)
from olatbench.datasets.formats._suite import SuiteDefaults, default_aliases
from olatbench.datasets.records import Frame, Scene

FORMAT_NAME = "nrhints"
DISPLAY_COLOURSPACE = "srgb"  # trained and scored in: 8-bit sRGB PNGs, used as stored
_SCENES = ("Cat", "CatSmall", "CupFabric", "Fish", "FurScene", "Pikachu", "Pixiu")
#: The paper's NRHints suite (512² or 1024² scenes: each at its own size).
SUITE_DEFAULTS = SuiteDefaults(
    scenes=_SCENES,
    aliases=default_aliases(
        _SCENES, {"Cat_on_Decor": "CatSmall", "Cluttered": "FurScene", "Cup-Fabric": "CupFabric"}
    ),
    resolution=None,
    iterations=100_000,
    protocol="ssdgs",
)
BLACK, WHITE = (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)


def scene_background(
    root: Path, metas: Mapping[str, tuple[Path, dict]]
) -> tuple[tuple[float, float, float], str]:
    """(background, why) of an NRHints scene (module docstring) from its folder and transforms
    files."""
    if (Path(root) / "synth.json").is_file():
        return (
            BLACK,
            "black (made by olatbench's generator, synth.json: rendered on an empty background)",
        )
    tops = [meta for _, meta in metas.values() if isinstance(meta, Mapping)]
    frames = [
        frame
        for meta in tops
        if isinstance(meta.get("frames"), list)
        for frame in meta["frames"][:1]
        if isinstance(frame, Mapping)
    ]
    calibrated = any("camera_intrinsics" in m for m in tops) or any(
        "camera_intrinsics" in f for f in frames
    )
    if not calibrated and any("camera_angle_x" in m for m in tops):
        return WHITE, (
            "white (NRHints synthetic scene: camera_angle_x, no camera_intrinsics; NRHints trains "
            "these on white, scripts/train_synthetic.sh)"
        )
    return BLACK, (
        "black (NRHints real capture: camera_intrinsics; NRHints trains these on black, "
        "scripts/train_real.sh)"
    )


FLAVOUR = NerfFlavour(
    format_name=FORMAT_NAME,
    default_ext=".png",
    colourspace="srgb",
    alpha_mode="straight",
    background=BLACK,
    background_rule=scene_background,
)


def detect(root: Path) -> bool:
    """A NeRF-style tree whose frames have one ``file_path`` (or ``img_path``) and PNG (not EXR)
    images."""
    root = Path(root)
    found = c.first_frame(root, (SPLIT_FILES["train"], SPLIT_FILES["test"], SPLIT_FILES["val"]))
    if found is None:
        return False
    _, _, frame = found
    return (
        ("file_path" in frame or "img_path" in frame)
        and "file_paths" not in frame
        and not _is_exr(root, frame)
    )


def _is_exr(root: Path, frame: Mapping[str, Any]) -> bool:
    """Whether a frame's image is an EXR: its ``img_path`` suffix (which wins, as in the reader),
    its ``file_ext``, its ``file_path`` suffix, or the file on disk."""
    ext, file_path = frame.get("file_ext"), frame.get("file_path")
    if isinstance(frame.get("img_path"), str):
        return frame["img_path"].lower().endswith(".exr")
    if isinstance(ext, str):
        return ext.lower().lstrip(".") == "exr"
    if not isinstance(file_path, str):
        return False
    if file_path.lower().endswith(".exr"):
        return True
    return not (root / f"{file_path}.png").is_file() and (root / f"{file_path}.exr").is_file()


def read_scene(root: Path, errors: list[DatasetError] | None = None) -> Scene:
    """Read an NRHints scene folder (aliases such as ``Cat_on_Decor`` become the paper's
    ``CatSmall``)."""
    root = Path(root)
    return read_nerf_scene(root, FLAVOUR, SUITE_DEFAULTS.canonical(root.name) or root.name, errors)


def _encode(rgba_linear: np.ndarray) -> np.ndarray:
    """Linear straight RGBA -> sRGB straight RGBA (the PNG content)."""
    rgb = colour.linear_to_srgb(rgba_linear[..., :3])
    return np.concatenate(
        [np.clip(rgb, 0.0, 1.0), np.clip(rgba_linear[..., 3:4], 0.0, 1.0)], axis=2
    )


def write_scene(scene: Scene, out_dir: Path, pixels: Callable[[Frame], np.ndarray]) -> Path:
    """Write NRHints files: 8-bit sRGB straight RGBA PNGs and ``transforms_<split>.json``."""
    return write_nerf_scene(scene, out_dir, FLAVOUR, _encode, pixels, "uint8")


def official_ground_truth(frame: Frame) -> np.ndarray:
    """sRGB PNG composited on the frame's background, truncated to 8 bits (GS³ / SSD-GS loader)."""
    rgb, alpha = c.stored_pixels(frame)
    composited = colour.composite(rgb, alpha, frame.background, "straight")
    return colour.dequantize_8bit(colour.quantize_8bit(composited, "truncate"))
