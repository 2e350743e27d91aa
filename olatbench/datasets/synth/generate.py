"""Recipe -> rendered frames -> a scene folder in any supported format.

`render_recipe` renders every frame into memory (`RenderedScene`: an in-memory `Scene` whose frames
have ``image_path=None``, plus linear straight-alpha RGBA arrays and the geometry pass);
`write_rendered` writes it through `olatbench.datasets.convert.write_scene` and adds
``geometry/<split>/<frame_id>.exr`` and ``synth.json`` (the recipe, the Mitsuba variant and
version). Every frame's sampler seed is derived from ``recipe.seed`` and the frame's index, so the
same recipe renders the same pixels on the same Mitsuba variant.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.atomic import write_json
from olatbench.datasets.errors import OutputExistsError
from olatbench.datasets.records import Frame, Scene
from olatbench.datasets.synth.backend import active_variant, mitsuba
from olatbench.datasets.synth.geometry import write_geometry
from olatbench.datasets.synth.meshes import TriangleMesh
from olatbench.datasets.synth.recipe import Recipe
from olatbench.datasets.synth.render import SceneRenderer
from olatbench.datasets.synth.rigs import make_rig

# bump when a change of code changes the pixels (v2: cameras aim at the real centre;
GENERATOR_VERSION = 3
#                       v3: no CPU-dependent numpy/BLAS arithmetic, `olatbench.datasets.portable`)


@dataclass(eq=False)
class RenderedScene:
    """A rendered recipe: ``scene`` (frames without files), ``pixels[(split, frame_id)]`` float32
    (H, W, 4) linear straight RGBA, ``geometry[(split, frame_id)]`` channel -> (H, W)
    (empty when skipped)."""

    recipe: Recipe
    scene: Scene
    pixels: dict[tuple[str, str], np.ndarray]
    geometry: dict[tuple[str, str], dict[str, np.ndarray]]
    mesh: TriangleMesh
    variant: str


def frame_seed(recipe: Recipe, index: int) -> int:
    """Sampler seed of the ``index``-th frame (train frames first, then test)."""
    return (recipe.seed * 1_000_003 + index) % (2**31)


def synth_metadata(recipe: Recipe, variant: str, centre: np.ndarray) -> dict[str, Any]:
    """What ``synth.json`` and ``Scene.metadata['synth']`` record about the generation."""
    return {
        "generator_version": GENERATOR_VERSION,
        "mitsuba_variant": variant,
        "mitsuba_version": mitsuba().__version__,
        "recipe": recipe.to_dict(),
        "object_bounding_sphere": {
            "centre": np.asarray(centre, dtype=float).tolist(),
            "radius": 1.0,
        },
        "alpha": "coverage of the object and the ground disc (both foreground); background empty",
        "frame_seed": "(recipe.seed * 1000003 + frame index) mod 2^31, train frames first",
    }


def render_recipe(
    recipe: Recipe, root: Path | None = None, progress: bool = True, geometry: bool = True
) -> RenderedScene:
    """Render every frame of ``recipe``; ``root`` becomes ``Scene.root``
    (where it will be written)."""
    from olatbench.progress import progress_bar

    renderer = SceneRenderer(recipe)
    variant = active_variant()
    centre = renderer.mesh.bounding_sphere()[0]
    rig = make_rig(recipe, centre)
    frames: dict[str, list[Frame]] = {}
    pixels: dict[tuple[str, str], np.ndarray] = {}
    passes: dict[tuple[str, str], dict[str, np.ndarray]] = {}
    total = sum(len(pairs) for pairs in rig.frames.values())
    index = 0
    with progress_bar(
        total=total, desc=f"rendering {recipe.name}", unit="img", disable=not progress
    ) as bar:
        for split, pairs in rig.frames.items():
            frames[split] = []
            for number, (camera, light) in enumerate(pairs):
                frame = Frame(
                    scene=recipe.name,
                    split=split,
                    frame_id=f"r_{number:04d}",
                    image_path=None,
                    camera=camera,
                    light=light,
                    colourspace="linear",
                    alpha_mode="straight",
                    background=np.zeros(3),
                    extras={"seed": frame_seed(recipe, index)},
                )
                pixels[(split, frame.frame_id)] = renderer.render(
                    camera, light, frame_seed(recipe, index)
                )
                if geometry:
                    passes[(split, frame.frame_id)] = renderer.geometry(
                        camera, frame_seed(recipe, index)
                    )
                frames[split].append(frame)
                index += 1
                bar.update()
    scene = Scene(
        name=recipe.name,
        format="synth",
        root=Path(root) if root is not None else Path("."),
        frames=frames,
        background=np.zeros(3),
        metadata={"synth": synth_metadata(recipe, variant, centre)},
    )
    return RenderedScene(recipe, scene, pixels, passes, renderer.mesh, variant)


def write_rendered(rendered: RenderedScene, out_dir: Path, fmt: str = "nrhints") -> Path:
    """Write a `RenderedScene` in format ``fmt`` plus its geometry pass and ``synth.json``; returns
    ``out_dir``."""
    from olatbench.datasets.convert import write_scene

    out_dir = Path(out_dir)
    write_scene(
        rendered.scene,
        out_dir,
        fmt,
        pixels=lambda frame: rendered.pixels[(frame.split, frame.frame_id)],
    )
    for (split, frame_id), channels in rendered.geometry.items():
        write_geometry(out_dir / "geometry" / split / f"{frame_id}.exr", channels)
    write_json(out_dir / "synth.json", rendered.scene.metadata["synth"])
    return out_dir


def generate(
    recipe: Recipe,
    out_dir: Path,
    fmt: str = "nrhints",
    progress: bool = True,
    geometry: bool = True,
) -> Path:
    """Render ``recipe`` and write it to ``out_dir`` in format ``fmt`` (refused, before rendering,
    when a scene already exists there)."""
    from olatbench.datasets.formats import is_scene_folder

    if is_scene_folder(Path(out_dir)):
        raise OutputExistsError(
            "a scene already exists here; choose another folder or delete it first", path=out_dir
        )
    rendered = render_recipe(recipe, root=out_dir, progress=progress, geometry=geometry)
    return write_rendered(rendered, out_dir, fmt)
