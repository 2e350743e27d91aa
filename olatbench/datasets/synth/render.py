"""Render one recipe's object, ground and point light with Mitsuba 3, frame by frame.

`SceneRenderer(recipe)` builds the Mitsuba scene once (object mesh with its BSDF or medium, ground
disc, one point light); `render(camera, light, seed)` moves the light and returns float32 (H, W, 4)
linear RGB with *straight* alpha, and `geometry(camera, seed)` the diagnostic pass. Alpha is the
coverage of object **and** ground disc (both are foreground, like the support under a real captured
object); the background is empty. Pixels are box-filtered: each pixel averages ``spp`` jittered
samples over its own square, pixel centres at +0.5 as in `olatbench.datasets.cameras`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from olatbench.datasets import colour, portable
from olatbench.datasets.records import Camera, PointLight
from olatbench.datasets.synth import meshes
from olatbench.datasets.synth.backend import mitsuba, sensor_dict
from olatbench.datasets.synth.recipe import Recipe
from olatbench.datasets.synth.textures import procedural_texture

GEOMETRY_SPP = 8
GEOMETRY_CHANNELS = ("A", "object", "N.X", "N.Y", "N.Z", "Z")


def object_mesh(recipe: Recipe) -> meshes.TriangleMesh:
    """The recipe's mesh, scaled to a unit bounding sphere resting on z = 0."""
    shape = recipe.shape
    mesh = (
        meshes.load_mesh_file(shape)
        if shape.lower().endswith((".ply", ".obj"))
        else meshes.procedural_mesh(shape)
    )
    return meshes.place_on_ground(mesh)


def _rgb(value: Any) -> dict:
    return {
        "type": "rgb",
        "value": [float(v) for v in np.broadcast_to(np.asarray(value, dtype=np.float64), (3,))],
    }


def _bsdf_and_medium(recipe: Recipe) -> tuple[dict, dict | None]:
    """Mitsuba dicts of the object's BSDF and interior medium (None for surfaces)."""
    mi = mitsuba()
    m = recipe.material
    if m.kind == "diffuse":
        if m.texture is None:
            return {"type": "diffuse", "reflectance": _rgb(m.albedo)}, None
        # the seed moves rigs only
        texture = procedural_texture(m.texture, m.albedo, scale=m.texture_scale)
        return {
            "type": "diffuse",
            "reflectance": {
                "type": "bitmap",
                "bitmap": mi.Bitmap(texture),
                "raw": True,
                "filter_type": "bilinear",
            },
        }, None
    if m.kind == "roughconductor":
        return {
            "type": "roughconductor",
            "material": m.conductor,
            "distribution": "ggx",
            "alpha_u": float(m.alpha_u),
            "alpha_v": float(m.alpha_v),
        }, None
    if m.kind == "roughplastic":
        return {
            "type": "roughplastic",
            "distribution": "ggx",
            "alpha": float(m.alpha),
            "int_ior": float(m.ior),
            "diffuse_reflectance": _rgb(m.albedo),
        }, None
    if m.kind == "translucent":
        medium = {
            "type": "homogeneous",
            "albedo": _rgb(m.albedo),
            "sigma_t": float(m.sigma_t),
            "phase": {"type": "hg", "g": float(m.g)},
        }
        return {"type": "null"}, medium
    raise ValueError(f"unknown material kind {m.kind!r}")


def _mitsuba_mesh(mesh: meshes.TriangleMesh, bsdf: dict, medium: dict | None):
    """A ``mi.Mesh`` with smooth normals and uvs, built from numpy arrays (no file)."""
    mi = mitsuba()
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    if medium is not None:
        props["interior"] = mi.load_dict(medium)
    shape = mi.Mesh(
        "object",
        len(mesh.vertices),
        len(mesh.faces),
        props=props,
        has_vertex_normals=True,
        has_vertex_texcoords=True,
    )
    params = mi.traverse(shape)
    for key, array, dtype in (
        ("vertex_positions", mesh.vertices, np.float32),
        ("vertex_normals", mesh.normals, np.float32),
        ("vertex_texcoords", mesh.uvs, np.float32),
        ("faces", mesh.faces, np.uint32),
    ):
        params[key] = type(params[key])(np.ascontiguousarray(array, dtype=dtype).reshape(-1))
    params.update()
    return shape


def scene_shapes(recipe: Recipe, mesh: meshes.TriangleMesh) -> tuple[dict[str, Any], Any]:
    """(the Mitsuba shapes of a recipe: object, and ground disc when it has one; the integrator that
    renders them, emitters hidden)."""
    mi = mitsuba()
    bsdf, medium = _bsdf_and_medium(recipe)
    shapes: dict[str, Any] = {"object": _mitsuba_mesh(mesh, bsdf, medium)}
    if recipe.ground:
        shapes["ground"] = {
            "type": "disk",
            "to_world": mi.ScalarTransform4f().scale(recipe.ground_radius),
            "bsdf": {"type": "diffuse", "reflectance": _rgb(recipe.ground_albedo)},
        }
    integrator = mi.load_dict(
        {
            "type": "volpath" if medium is not None else "path",
            "max_depth": int(recipe.max_depth),
            "hide_emitters": True,
        }
    )
    return shapes, integrator


def straight_rgba(image: np.ndarray) -> np.ndarray:
    """A Mitsuba render (H, W, 4: premultiplied RGB, alpha) as float32 linear RGB with straight
    alpha."""
    alpha = np.clip(image[..., 3], 0.0, 1.0)
    rgb = colour.unpremultiply(image[..., :3], alpha)
    return np.concatenate([rgb, alpha[..., None]], axis=2).astype(np.float32)


class SceneRenderer:
    """The Mitsuba scene of one recipe; renders any (camera, light) pair."""

    def __init__(self, recipe: Recipe, mesh: meshes.TriangleMesh | None = None) -> None:
        mi = mitsuba()
        self.recipe = recipe.validate()
        self.mesh = object_mesh(recipe) if mesh is None else mesh
        shapes, self._integrator = scene_shapes(recipe, self.mesh)
        self._scene = mi.load_dict(
            {
                "type": "scene",
                **shapes,
                "light": {
                    "type": "point",
                    "position": [0.0, 0.0, 10.0],
                    "intensity": _rgb(recipe.lights.intensity),
                },
            }
        )
        self._light_params = mi.traverse(self._scene)
        self._object_only = mi.load_dict(
            {"type": "scene", "object": _mitsuba_mesh(self.mesh, {"type": "diffuse"}, None)}
        )
        self._geometry_integrator = mi.load_dict(
            {"type": "aov", "aovs": "n:sh_normal,p:position", "integrator": {"type": "depth"}}
        )

    def render(self, camera: Camera, light: PointLight, seed: int) -> np.ndarray:
        """Linear RGB + straight alpha, float32 (H, W, 4), for one camera and point light."""
        mi = mitsuba()
        params = self._light_params
        params["light.position"] = type(params["light.position"])(
            *np.asarray(light.position, dtype=float)
        )
        params["light.intensity.value"] = type(params["light.intensity.value"])(
            *np.asarray(light.intensity, dtype=float)
        )
        params.update()
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

    def geometry(self, camera: Camera, seed: int = 0) -> dict[str, np.ndarray]:
        """Diagnostic pass, (H, W) arrays: ``A`` foreground coverage, ``object`` object coverage,
        ``N.X/Y/Z`` world shading normal and ``Z`` OpenCV camera depth, both averaged over the
        covered samples (0 where nothing is hit; mixtures at silhouettes)."""
        mi = mitsuba()
        sensor = mi.load_dict(sensor_dict(camera, GEOMETRY_SPP))
        full = np.array(
            mi.render(
                self._scene,
                sensor=sensor,
                integrator=self._geometry_integrator,
                seed=int(seed),
                spp=GEOMETRY_SPP,
            ),
            dtype=np.float64,
        )
        only = np.array(
            mi.render(
                self._object_only,
                sensor=sensor,
                integrator=self._geometry_integrator,
                seed=int(seed),
                spp=GEOMETRY_SPP,
            ),
            dtype=np.float64,
        )
        coverage = full[..., 3]
        covered = np.maximum(coverage, 1e-8)[..., None]
        normal = full[..., 4:7] / covered
        normal /= np.maximum(portable.norm(normal, keepdims=True), 1e-8)
        position = full[..., 7:10] / covered
        # along the view axis (OpenCV z)
        depth = portable.dot(position - camera.position, camera.c2w[:3, 2])
        hit = coverage > 0
        out = {
            "A": coverage,
            "object": only[..., 3],
            "N.X": normal[..., 0] * hit,
            "N.Y": normal[..., 1] * hit,
            "N.Z": normal[..., 2] * hit,
            "Z": depth * hit,
        }
        return {name: out[name].astype(np.float32) for name in GEOMETRY_CHANNELS}
