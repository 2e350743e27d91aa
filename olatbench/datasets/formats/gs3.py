"""GS³ (Bi et al. 2024) synthetic OLAT scenes.

Files: ``transforms_{train,test}.json`` with ``camera_angle_x``, ``camera_near``/``camera_far``, per
frame ``file_path`` + ``file_ext`` (".exr"), ``pl_pos``, ``pl_intensity``, optional per-frame
``camera_intrinsics`` and refined poses ``R_opt``/``T_opt`` (which, as in the official readers, give
the frame's camera; ``transform_matrix``'s pose stays in ``Frame.extras``). Images: float RGBA EXR,
linear light, premultiplied alpha; official background white.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Literal

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
from olatbench.datasets.formats.nrhints import _is_exr
from olatbench.datasets.records import Frame, Scene

FORMAT_NAME = "gs3"
# Trained and scored in: the official GS³/SSD-GS code shows its linear EXRs with a pure 2.2 gamma.
DISPLAY_COLOURSPACE = "gamma22"
_SCENES = ("Translucent", "AnisoMetal", "Drums", "FurBall", "Hotdog", "Lego")
#: The paper's GS³ suite (512²).
SUITE_DEFAULTS = SuiteDefaults(
    scenes=_SCENES,
    aliases=default_aliases(_SCENES),
    resolution=(512, 512),
    iterations=100_000,
    protocol="ssdgs",
)
FLAVOUR = NerfFlavour(
    format_name=FORMAT_NAME,
    default_ext=".exr",
    colourspace="linear",
    alpha_mode="premultiplied",
    background=(1.0, 1.0, 1.0),
    angle_first=True,
)


def detect(root: Path) -> bool:
    """A NeRF-style tree whose first frame is an EXR (``file_ext`` ".exr", a ``file_path`` ending in
    it, or on disk)."""
    root = Path(root)
    found = c.first_frame(root, (SPLIT_FILES["train"], SPLIT_FILES["test"], SPLIT_FILES["val"]))
    if found is None:
        return False
    _, _, frame = found
    return "file_paths" not in frame and _is_exr(root, frame)


def read_scene(root: Path, errors: list[DatasetError] | None = None) -> Scene:
    """Read a GS³ scene folder."""
    root = Path(root)
    return read_nerf_scene(root, FLAVOUR, SUITE_DEFAULTS.canonical(root.name) or root.name, errors)


def _encode(rgba_linear: np.ndarray) -> np.ndarray:
    """Linear straight RGBA -> linear premultiplied RGBA (the EXR content)."""
    alpha = np.clip(rgba_linear[..., 3], 0.0, 1.0)
    return np.concatenate(
        [colour.premultiply(np.clip(rgba_linear[..., :3], 0.0, None), alpha), alpha[..., None]],
        axis=2,
    )


def write_scene(scene: Scene, out_dir: Path, pixels: Callable[[Frame], np.ndarray]) -> Path:
    """Write GS³ files: half-float linear premultiplied RGBA EXRs and
    ``transforms_<split>.json``."""
    return write_nerf_scene(scene, out_dir, FLAVOUR, _encode, pixels, "half")


def official_ground_truth(frame: Frame) -> np.ndarray:
    """The official loader's image (`loader_image` with its alpha quirk and 8-bit rounding)."""
    return loader_image(frame)


def loader_image(
    frame: Frame, alpha_quirk: bool = True, quantize: Literal["round", "truncate"] | None = "round"
) -> np.ndarray:
    """Linear EXR composited on the frame's background (white), gamma 2.2 encoded, clipped to [0, 1]
    and quantised to 8 bits (``quantize=None`` keeps the clipped floats); ``alpha_quirk=False``
    composites the premultiplied EXR correctly (the official loader uses the straight-alpha formula,
    `olatbench.datasets.official`)."""
    rgb, alpha = c.stored_pixels(frame)
    mode = "straight" if alpha_quirk else "premultiplied"
    encoded = colour.gamma_encode(colour.composite(rgb, alpha, frame.background, mode))
    if quantize is None:
        return np.clip(encoded, 0.0, 1.0)
    return colour.dequantize_8bit(colour.quantize_8bit(encoded, quantize))
