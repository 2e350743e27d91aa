"""Scene recipes: everything that decides a synthetic OLAT scene, as plain frozen dataclasses.

World frame: z is up, the object's bounding sphere has radius 1 and the object rests on the ground
plane z = 0, centred on the z axis; cameras and lights are placed around the bounding-sphere centre.
Distances are in these units. Light intensities are radiant
intensities (W/sr in Mitsuba's units): the irradiance at distance d is ``intensity / d²``.
A recipe is serialisable to JSON (`Recipe.to_dict` / `Recipe.from_dict`) and built-in recipes are
listed in `RECIPES`.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from olatbench.datasets.sizes import checked_size

MaterialKind = Literal["diffuse", "roughconductor", "roughplastic", "translucent"]
RGB = tuple[float, float, float]


@dataclass(frozen=True)
class Material:
    """The object's BSDF (and medium).

    * ``diffuse``: Lambertian, ``albedo`` (linear RGB) or a procedural ``texture`` tinted by it;
    * ``roughconductor``: GGX metal ``conductor`` (Mitsuba material name, e.g. ``"Cu"``) with
      roughness ``alpha_u`` along the mesh's u direction and ``alpha_v`` along v
      (anisotropic when they differ);
    * ``roughplastic``: ``albedo`` diffuse base under a GGX coat of roughness ``alpha`` and index
      ``ior``;
    * ``translucent``: a homogeneous medium (extinction ``sigma_t`` per unit length,
      single-scattering ``albedo``, Henyey-Greenstein ``g``) inside an index-matched (``null``)
      boundary, rendered with ``volpath``. Index matching lets next-event estimation reach the point
      lights through the surface.
    """

    kind: MaterialKind = "diffuse"
    albedo: RGB = (0.6, 0.45, 0.3)
    texture: str | None = None
    texture_scale: float = 8.0
    conductor: str = "Cu"
    alpha_u: float = 0.05
    alpha_v: float = 0.3
    alpha: float = 0.15
    ior: float = 1.5
    sigma_t: float = 8.0
    g: float = 0.3


@dataclass(frozen=True)
class CameraRig:
    """Cameras on a spherical band around the object's bounding-sphere centre, looking at it.

    ``radius``: distance to the bounding-sphere centre; ``elevation_deg``: (min, max) above the
    horizontal; ``fill``: fraction of the image width covered by the bounding sphere (sets the field
    of view); ``near``/``far``: clip distances stored with the cameras.
    """

    radius: float = 4.0
    elevation_deg: tuple[float, float] = (10.0, 65.0)
    fill: float = 0.8
    near: float = 0.1
    far: float = 100.0


@dataclass(frozen=True)
class LightRig:
    """Point lights on a spherical band of ``radius`` around the object centre, of RGB ``intensity``
    (W/sr)."""

    radius: float = 5.0
    elevation_deg: tuple[float, float] = (15.0, 80.0)
    intensity: RGB = (80.0, 80.0, 80.0)


@dataclass(frozen=True)
class Recipe:
    """A synthetic OLAT scene: shape, material, ground, rigs, image size, sampling and split sizes.

    ``shape``: a procedural shape name (`meshes.PROCEDURAL_SHAPES`) or a path to a PLY/OBJ file.
    ``ground``: a diffuse disc of ``ground_radius`` and ``ground_albedo`` under the object; it is
    part of the foreground (alpha 1), like the support of the real captures. ``max_depth``: path
    length (2 = direct light only). Train and test frames use disjoint light positions; test cameras
    are the training cameras unless ``novel_views``.
    """

    name: str
    shape: str = "sphere"
    material: Material = field(default_factory=Material)
    ground: bool = True
    ground_radius: float = 2.2
    ground_albedo: RGB = (0.5, 0.5, 0.5)
    cameras: CameraRig = field(default_factory=CameraRig)
    lights: LightRig = field(default_factory=LightRig)
    resolution: tuple[int, int] = (80, 80)
    spp: int = 64
    max_depth: int = 8
    train: int = 100
    test: int = 20
    novel_views: bool = False
    seed: int = 0

    def with_overrides(self, **overrides: Any) -> Recipe:
        """A copy with top-level fields replaced (None values are ignored)."""
        return dataclasses.replace(self, **{k: v for k, v in overrides.items() if v is not None})

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "recipe") -> Recipe:
        """Build from a JSON-like dict; an unknown or mistyped key raises `ValueError` naming it."""
        nested = {"material": Material, "cameras": CameraRig, "lights": LightRig}
        return _build(cls, data, source, nested)

    def validate(self) -> Recipe:
        """Raise `ValueError` naming the first impossible field; return self."""
        try:
            checked_size(*self.resolution, minimum=4)
        except (TypeError, ValueError) as error:
            raise ValueError(f"recipe '{self.name}': resolution {error}") from None
        checks = [
            (self.spp >= 1, "spp", f"must be ≥ 1, found {self.spp}"),
            (self.train >= 1, "train", f"must be ≥ 1, found {self.train}"),
            (self.test >= 0, "test", f"must be ≥ 0, found {self.test}"),
            (
                self.max_depth >= 2 or self.max_depth == -1,
                "max_depth",
                "must be ≥ 2 (or -1 for unbounded)",
            ),
            (
                self.cameras.radius > 1.0 + self.cameras.near,
                "cameras.radius",
                "must exceed the bounding sphere (1) plus the near distance",
            ),
            (self.lights.radius > 1.0, "lights.radius", "must exceed the bounding sphere (1)"),
            (
                0.0 < self.cameras.fill < 1.5,
                "cameras.fill",
                f"must be in (0, 1.5), found {self.cameras.fill}",
            ),
            (
                self.material.kind in ("diffuse", "roughconductor", "roughplastic", "translucent"),
                "material.kind",
                f"unknown material {self.material.kind!r}",
            ),
        ]
        for ok, key, message in checks:
            if not ok:
                raise ValueError(f"recipe '{self.name}': {key} {message}")
        return self


def _build(cls: type, data: Any, source: str, nested: dict[str, type]) -> Any:
    if not isinstance(data, dict):
        raise ValueError(f"{source}: expected a JSON object for {cls.__name__}")
    names = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - set(names))
    if unknown:
        raise ValueError(
            f"{source}: unknown key(s) {', '.join(unknown)} for {cls.__name__}; "
            f"expected some of {', '.join(names)}"
        )
    values = {}
    for key, value in data.items():
        if key in nested:
            values[key] = _build(nested[key], value, f"{source}.{key}", {})
        elif isinstance(value, list):
            values[key] = tuple(value)
        else:
            values[key] = value
    try:
        return cls(**values)
    except TypeError as error:
        raise ValueError(f"{source}: {error}") from None


# Direct light only (max_depth 2) for the glossy recipes: at these sample counts their
# interreflections (the ground seen in the metal, caustics of the coat on the ground) would be
# fireflies, not signal.
RECIPES: dict[str, Recipe] = {
    "diffuse_shadow": Recipe(
        name="diffuse_shadow",
        shape="blob",
        max_depth=4,
        material=Material(
            kind="diffuse", albedo=(0.75, 0.45, 0.2), texture="checker", texture_scale=8.0
        ),
    ),
    "aniso_metal": Recipe(
        name="aniso_metal",
        shape="torus",
        max_depth=2,
        material=Material(kind="roughconductor", conductor="Cu", alpha_u=0.06, alpha_v=0.4),
    ),
    "translucent": Recipe(
        name="translucent",
        shape="rounded_box",
        spp=128,
        max_depth=32,
        material=Material(kind="translucent", albedo=(0.95, 0.85, 0.7), sigma_t=4.0, g=0.3),
    ),
    "glossy_plastic": Recipe(
        name="glossy_plastic",
        shape="sphere",
        max_depth=2,
        material=Material(kind="roughplastic", albedo=(0.1, 0.25, 0.6), alpha=0.12, ior=1.5),
    ),
    "marble_box": Recipe(
        name="marble_box",
        shape="rounded_box",
        max_depth=4,
        material=Material(
            kind="diffuse", albedo=(0.8, 0.8, 0.75), texture="marble", texture_scale=4.0
        ),
    ),
}


def recipe_names() -> list[str]:
    return sorted(RECIPES)


def get_recipe(name_or_file: str | Path) -> Recipe:
    """A built-in recipe by name, or one read from a JSON file (a relative ``shape`` path is
    resolved against the file's folder)."""
    if str(name_or_file) in RECIPES:
        return RECIPES[str(name_or_file)]
    path = Path(name_or_file)
    if not path.is_file():
        raise ValueError(
            f"unknown recipe {str(name_or_file)!r}: not a built-in ({', '.join(recipe_names())}) "
            f"and not a JSON file"
        )
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as error:
        raise ValueError(f"{path}: cannot read the recipe ({error})") from None
    if isinstance(data, dict):
        data.setdefault("name", path.stem)
        shape = data.get("shape")
        if (
            isinstance(shape, str)
            and shape.lower().endswith((".ply", ".obj"))
            and not Path(shape).is_absolute()
        ):
            data["shape"] = str(path.parent / shape)
    return Recipe.from_dict(data, source=str(path)).validate()
