"""Ground truth under a lighting: a recipe's test cameras rendered with Mitsuba 3 under every light
of a lighting (`olatbench.datasets.lighting`) at once.

The scene is the recipe's (`olatbench.datasets.synth.render.scene_shapes`: object, ground disc,
integrator with the emitters hidden, so the background stays empty) and the cameras are its test
split's (`make_rig`, the same as `olatbench datasets synth --recipe` writes). The emitters are the
lighting's, in Mitsuba terms:

* point lights: ``point`` emitters (RGB intensity); area lights: their sampled isotropic points,
  drawn as `Lighting.sample` draws them (the description *is* those points, docs/relighting.md), so
  a model and the ground truth see the same lights;
* directional lights: ``directional`` emitters (RGB irradiance, propagating along ``-direction``);
* environment maps: one ``envmap`` emitter each, the **whole** map (not its samples), with its
  rotation and exposure. Mitsuba's map frame differs from olatbench's
  (`olatbench.datasets.lighting.envmap`): its up is local +y and its azimuth turns clockwise about
  it, starting at local −z. `envmap_emitter` passes the map with its columns reversed and a
  ``to_world`` taking local +y to up, −z to the map's x axis and +x to minus its y axis, then turned
  by ``rotation`` about up, so every direction sees the radiance olatbench's convention gives it.

`render_lit` writes ``<frame_id>.exr`` (linear RGB, straight alpha; float, or half for the packaged
ground truth) per test frame, ``lighting.json`` (the lighting file, maps given by file named by
their absolute path, so that it reads back from the folder) and ``lit.json``: the lighting, the
recipe, the cameras (``K``, OpenCV ``c2w``, size) and the generator and Mitsuba versions. A folder
of these is one condition of a scene's ground truth under new illumination
(`olatbench.datasets.novel_lights`: ``<scene>/novel_lights/<condition>/``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.atomic import write_json
from olatbench.datasets.errors import OutputExistsError
from olatbench.datasets.images import BitDepth
from olatbench.datasets.lighting import (
    DirectionalLight,
    EnvironmentMap,
    Lighting,
    LightSource,
    lighting_to_dict,
    write_lighting,
)
from olatbench.datasets.lighting.envmap import BUILT_IN_MAPS, map_axes
from olatbench.datasets.records import Camera
from olatbench.datasets.synth.backend import active_variant, mitsuba, sensor_dict
from olatbench.datasets.synth.recipe import Recipe
from olatbench.datasets.synth.render import _rgb, object_mesh, scene_shapes, straight_rgba
from olatbench.datasets.synth.rigs import make_rig

SCENE_UP = np.array([0.0, 0.0, 1.0])  # the recipes' vertical: the object rests on z = 0


def envmap_to_world(up: np.ndarray, rotation_deg: float) -> np.ndarray:
    """(4, 4) ``to_world`` of Mitsuba's envmap for a map standing on ``up`` turned by
    ``rotation_deg`` (module docstring): columns local x, y, z -> −(map y), up, −(map x), then the
    turn about up."""
    x, y, vertical = map_axes(up)
    basis = np.stack([-y, vertical, -x], axis=1)
    angle = np.radians(rotation_deg)
    cross = np.array(
        [
            [0.0, -vertical[2], vertical[1]],
            [vertical[2], 0.0, -vertical[0]],
            [-vertical[1], vertical[0], 0.0],
        ]
    )
    turn = np.eye(3) + np.sin(angle) * cross + (1.0 - np.cos(angle)) * (cross @ cross)
    matrix = np.eye(4)
    matrix[:3, :3] = turn @ basis
    return matrix


def envmap_emitter(source: EnvironmentMap, up: np.ndarray) -> dict[str, Any]:
    """The Mitsuba ``envmap`` emitter dict of one map (module docstring)."""
    mi = mitsuba()
    radiance = source.radiance()[:, ::-1] * 2.0**source.exposure
    return {
        "type": "envmap",
        "bitmap": mi.Bitmap(np.ascontiguousarray(radiance, dtype=np.float32)),
        "to_world": mi.ScalarTransform4f(
            envmap_to_world(source.up if source.up is not None else up, source.rotation).tolist()
        ),
    }


def emitters(lighting: Lighting, up: np.ndarray = SCENE_UP) -> dict[str, dict[str, Any]]:
    """Mitsuba emitter dicts (named ``light_<i>``) of every light of ``lighting``: its point lights
    and the points of its area lights exactly as `Lighting.sample` draws them, its directional
    lights, and its maps whole (those without an ``up`` stand on ``up``)."""
    out: dict[str, dict[str, Any]] = {}
    for light in lighting.sample(up).points:
        out[f"light_{len(out)}"] = {
            "type": "point",
            "position": [float(v) for v in light.position],
            "intensity": _rgb(light.intensity),
        }
    for source in lighting.sources:
        if isinstance(source, DirectionalLight):
            out[f"light_{len(out)}"] = {
                "type": "directional",
                "direction": [float(-v) for v in source.direction],
                "irradiance": _rgb(source.irradiance),
            }
        elif isinstance(source, EnvironmentMap):
            out[f"light_{len(out)}"] = envmap_emitter(source, up)
    return out


def with_absolute_maps(lighting: Lighting) -> Lighting:
    """``lighting`` with every map given by a relative file path named by its absolute path instead
    (a lighting file written elsewhere then still finds its maps)."""

    def absolute(source: LightSource) -> LightSource:
        if not isinstance(source, EnvironmentMap) or source.source in BUILT_IN_MAPS:
            return source
        path = Path(source.source)
        path = path if path.is_absolute() or source.base is None else Path(source.base) / path
        return dataclasses.replace(source, source=str(path.resolve()), base=None)

    return dataclasses.replace(
        lighting, sources=tuple(absolute(source) for source in lighting.sources)
    )


class LitRenderer:
    """A recipe's Mitsuba scene under a lighting; renders any camera."""

    def __init__(self, recipe: Recipe, lighting: Lighting) -> None:
        mi = mitsuba()
        self.recipe = recipe.validate()
        self.mesh = object_mesh(recipe)
        shapes, self._integrator = scene_shapes(recipe, self.mesh)
        self._scene = mi.load_dict({"type": "scene", **shapes, **emitters(lighting)})

    def render(self, camera: Camera, seed: int) -> np.ndarray:
        """Linear RGB + straight alpha, float32 (H, W, 4)."""
        mi = mitsuba()
        sensor = mi.load_dict(sensor_dict(camera, self.recipe.spp))
        return straight_rgba(
            np.array(
                mi.render(
                    self._scene,
                    sensor=sensor,
                    integrator=self._integrator,
                    seed=int(seed),
                    spp=self.recipe.spp,
                ),
                dtype=np.float32,
            )
        )


def render_lit(
    recipe: Recipe,
    lighting: Lighting,
    out_dir: Path,
    progress: bool = True,
    bit_depth: BitDepth = "float",
    mantissa_bits: int | None = None,
) -> Path:
    """Render ``recipe``'s test cameras under ``lighting`` into ``out_dir`` (module docstring;
    refused, before rendering, when the folder exists and is not empty), the EXRs at ``bit_depth``
    (``float`` or ``half``), with ``mantissa_bits``: half colours rounded to this many mantissa bits
    (`round_half_mantissa`; alpha kept as half); returns ``out_dir``."""
    from olatbench.datasets.images import round_half_mantissa, write_image
    from olatbench.datasets.synth.generate import GENERATOR_VERSION, frame_seed
    from olatbench.progress import progress_bar

    out_dir = Path(out_dir)
    if out_dir.exists() and (not out_dir.is_dir() or any(out_dir.iterdir())):
        raise OutputExistsError(
            "the folder for the renders under a lighting is not empty; choose another", path=out_dir
        )
    lighting = with_absolute_maps(lighting)
    renderer = LitRenderer(recipe, lighting)
    rig = make_rig(recipe, renderer.mesh.bounding_sphere()[0])
    train, test = rig.frames.get("train", []), rig.frames.get("test", [])
    if not test:
        raise ValueError(
            f"recipe '{recipe.name}' has no test cameras to render under a lighting (test = 0)"
        )
    cameras = {}
    for number, (camera, _) in enumerate(
        progress_bar(
            test, desc=f"{recipe.name} under {lighting.name}", unit="img", disable=not progress
        )
    ):
        # the test frames' ids in the recipe's scene (generate.render_recipe)
        frame_id = f"r_{number:04d}"
        seed = frame_seed(recipe, len(train) + number)
        pixels = renderer.render(camera, seed)
        if mantissa_bits is not None:
            pixels[..., :3] = round_half_mantissa(pixels[..., :3], mantissa_bits)
        write_image(out_dir / f"{frame_id}.exr", pixels, bit_depth=bit_depth)
        cameras[frame_id] = {
            "K": np.asarray(camera.K).tolist(),
            "c2w": np.asarray(camera.c2w).tolist(),
            "width": camera.width,
            "height": camera.height,
            "seed": seed,
        }
    write_lighting(out_dir / "lighting.json", lighting)
    write_json(
        out_dir / "lit.json",
        {
            "lighting": lighting_to_dict(lighting),
            "recipe": recipe.to_dict(),
            "split": "test",
            "frames": cameras,
            "generator_version": GENERATOR_VERSION,
            "mitsuba_version": mitsuba().__version__,
            "mitsuba_variant": active_variant(),
            "pixels": (
                "linear RGB, straight alpha (coverage of object and ground disc); background empty"
            ),
        },
    )
    return out_dir


__all__ = [
    "LitRenderer",
    "emitters",
    "envmap_emitter",
    "envmap_to_world",
    "render_lit",
    "with_absolute_maps",
]
