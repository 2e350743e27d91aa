"""Mitsuba 3 access: the variant probe, the one camera-axis conversion, and mesh file reading.

Mitsuba is optional (``pip install 'olatbench[synth]'``) and imported only here, on first use. The
variant is ``llvm_ad_rgb`` when a probe renders a tiny scene with it in a *subprocess* (a mismatched
libLLVM aborts the whole process, which must not take the caller down), else ``scalar_rgb``;
``OLATBENCH_MITSUBA_VARIANT`` overrides the probe. The result is cached per process.
`pinned_variant` fixes the variant for a block (the ``mini`` suite renders with ``scalar_rgb``
everywhere, so its pixels do not depend on whether a machine has LLVM); the environment variable
still wins.
"""

from __future__ import annotations

import contextlib
import functools
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import numpy as np

from olatbench.datasets.records import Camera

VARIANT_ENV = "OLATBENCH_MITSUBA_VARIANT"
INSTALL_HINT = "pip install 'olatbench[synth]'"

_PROBE_SCRIPT = """
import mitsuba as mi
mi.set_variant("llvm_ad_rgb")
scene = mi.load_dict({"type": "scene", "integrator": {"type": "path"},
                      "sphere": {"type": "sphere", "bsdf": {"type": "roughconductor",
                                                            "alpha_u": 0.1, "alpha_v": 0.3}},
                      "light": {"type": "point", "position": [0, 0, 4]},
                      "sensor": {"type": "perspective", "to_world": mi.ScalarTransform4f().look_at(
                          origin=[0, -4, 1], target=[0, 0, 0], up=[0, 0, 1]),
                          "film": {"type": "hdrfilm", "width": 8, "height": 8}}})
image = mi.render(scene, spp=2)
assert image.shape == (8, 8, 3)
"""


class MitsubaMissing(ImportError):
    """Mitsuba 3 is not installed; the message says how to install it."""


def _import_mitsuba() -> ModuleType:
    try:
        import mitsuba
    except ImportError as error:
        raise MitsubaMissing(
            f"rendering synthetic scenes needs Mitsuba 3: {INSTALL_HINT} ({error})"
        ) from error
    return mitsuba


@functools.cache
def probe_variant() -> str:
    """``$OLATBENCH_MITSUBA_VARIANT``, else ``llvm_ad_rgb`` if a subprocess renders with it, else
    ``scalar_rgb``."""
    override = os.environ.get(VARIANT_ENV)
    if override:
        return override
    _import_mitsuba()
    try:
        result = subprocess.run(
            [sys.executable, "-c", _PROBE_SCRIPT], capture_output=True, timeout=300
        )
        works = result.returncode == 0
    except subprocess.TimeoutExpired:
        works = False
    return "llvm_ad_rgb" if works else "scalar_rgb"


_pinned: list[str] = []


@contextlib.contextmanager
def pinned_variant(variant: str) -> Iterator[None]:
    """Render with ``variant`` inside the block unless ``$OLATBENCH_MITSUBA_VARIANT`` names
    another."""
    _pinned.append(variant)
    try:
        yield
    finally:
        _pinned.pop()


def active_variant() -> str:
    """``$OLATBENCH_MITSUBA_VARIANT``, else the innermost `pinned_variant`, else `probe_variant`."""
    return os.environ.get(VARIANT_ENV) or (_pinned[-1] if _pinned else probe_variant())


def mitsuba() -> ModuleType:
    """The ``mitsuba`` module with the active variant set (raises `MitsubaMissing` without it)."""
    mi = _import_mitsuba()
    variant = active_variant()
    if variant not in mi.variants():
        raise ValueError(
            f"Mitsuba variant {variant!r} (from ${VARIANT_ENV}, a pin or the probe) is not "
            f"available; this build has {', '.join(mi.variants())}"
        )
    if mi.variant() != variant:
        mi.set_variant(variant)
    return mi


# Mitsuba cameras look down +z with x to the *left* and y *up* in the image; OpenCV cameras have
# x right and y down. Flipping the camera x and y axes maps one onto the other.
_OPENCV_TO_MITSUBA_AXES = np.diag([-1.0, -1.0, 1.0, 1.0])


def mitsuba_camera_to_world(c2w_opencv: np.ndarray) -> np.ndarray:
    """Camera-to-world (4, 4) in OpenCV axes -> Mitsuba sensor ``to_world`` (4, 4). The only
    conversion."""
    return np.asarray(c2w_opencv, dtype=np.float64) @ _OPENCV_TO_MITSUBA_AXES


def sensor_dict(camera: Camera, spp: int) -> dict:
    """A Mitsuba ``perspective`` sensor reproducing ``camera`` exactly
    (box pixel filter, RGBA film).

    Requires square pixels and the principal point at the image centre (what the rigs produce).
    """
    from olatbench.datasets.cameras import fov_from_focal

    mi = mitsuba()
    if not np.isclose(camera.fx, camera.fy, rtol=1e-9):
        raise ValueError(f"Mitsuba sensors need square pixels; fx={camera.fx}, fy={camera.fy}")
    if not (np.isclose(camera.cx, camera.width / 2) and np.isclose(camera.cy, camera.height / 2)):
        raise ValueError(
            f"the principal point ({camera.cx}, {camera.cy}) must be the image centre "
            f"({camera.width / 2}, {camera.height / 2})"
        )
    return {
        "type": "perspective",
        "fov": float(np.degrees(fov_from_focal(camera.fx, camera.width))),
        "fov_axis": "x",
        "near_clip": float(camera.near if camera.near is not None else 0.01),
        "far_clip": float(camera.far if camera.far is not None else 1e4),
        "to_world": mi.ScalarTransform4f(mitsuba_camera_to_world(camera.c2w).tolist()),
        "film": {
            "type": "hdrfilm",
            "width": int(camera.width),
            "height": int(camera.height),
            "pixel_format": "rgba",
            "rfilter": {"type": "box"},
        },
        "sampler": {"type": "independent", "sample_count": int(spp)},
    }


def read_mesh_file(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(vertices (V, 3), faces (F, 3), uvs (V, 2) or None) of a PLY/OBJ file, read by Mitsuba."""
    mi = mitsuba()
    try:
        shape = mi.load_dict({"type": path.suffix.lower().lstrip("."), "filename": str(path)})
    except Exception as error:
        raise ValueError(f"{path}: Mitsuba cannot read this mesh ({error})") from None
    params = mi.traverse(shape)
    vertices = np.array(params["vertex_positions"], dtype=np.float64).reshape(-1, 3)
    faces = np.array(params["faces"], dtype=np.int64).reshape(-1, 3)
    uvs = (
        np.array(params["vertex_texcoords"], dtype=np.float64).reshape(-1, 2)
        if shape.has_vertex_texcoords()
        else None
    )
    return vertices, faces, uvs
