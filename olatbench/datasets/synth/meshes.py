"""Procedural closed triangle meshes in numpy: sphere, torus, rounded box and a displaced blob.

Every mesh is a (u, v) grid over a closed parametrisation. Vertices along the texture seam and at
the poles are duplicated so that texture coordinates stay continuous; geometrically the surface is
closed (`is_watertight` checks it after welding coincident vertices). Normals are area-weighted
averages over the welded mesh, so they are smooth across the seam. Units are arbitrary;
`place_on_ground` scales a mesh to a bounding sphere of radius 1 resting on the plane z = 0
(z is world up).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from olatbench.datasets import portable


@dataclass(frozen=True, eq=False)
class TriangleMesh:
    """``vertices`` (V, 3) float64, ``faces`` (F, 3) int64 counter-clockwise seen from outside,
    ``uvs`` (V, 2) texture coordinates in [0, 1], ``normals`` (V, 3) unit outward vertex normals."""

    vertices: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray
    normals: np.ndarray

    def bounding_sphere(self) -> tuple[np.ndarray, float]:
        """(centre (3,), radius): centred on the bounding box, radius to the farthest vertex."""
        centre = 0.5 * (self.vertices.min(axis=0) + self.vertices.max(axis=0))
        return centre, float(np.max(portable.norm(self.vertices - centre)))


def weld(vertices: np.ndarray, decimals: int = 9) -> np.ndarray:
    """Index (V,) of each vertex's representative among vertices at the same position (rounded)."""
    _, first, inverse = np.unique(
        np.round(vertices, decimals), axis=0, return_index=True, return_inverse=True
    )
    return first[inverse.reshape(-1)]


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals (V, 3), shared by coincident (welded) vertices."""
    representative = weld(vertices)
    corners = vertices[faces]
    # length = 2 × area
    face_normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    accumulated = np.zeros_like(vertices)
    for corner in range(3):
        np.add.at(accumulated, representative[faces[:, corner]], face_normals)
    normals = accumulated[representative]
    return normals / np.maximum(portable.norm(normals, keepdims=True), 1e-12)


def is_watertight(mesh: TriangleMesh) -> bool:
    """True when, after welding coincident vertices, every edge is shared by exactly two faces
    traversed in opposite directions (a closed, consistently oriented surface)."""
    welded = weld(mesh.vertices)[mesh.faces]
    directed = np.concatenate([welded[:, [0, 1]], welded[:, [1, 2]], welded[:, [2, 0]]])
    if np.any(directed[:, 0] == directed[:, 1]):
        return False
    forward, forward_counts = np.unique(directed, axis=0, return_counts=True)
    backward = np.unique(directed[:, ::-1], axis=0)
    return bool(
        np.all(forward_counts == 1)
        and len(forward) == len(backward)
        and np.array_equal(forward, backward)
    )


def _grid_mesh(points: np.ndarray, uvs: np.ndarray) -> TriangleMesh:
    """Triangulate a (rows, cols, 3) grid of points; drop degenerate triangles.

    Faces are counter-clockwise seen from the side of ``d(row) × d(col)``: the grid must be laid out
    so that this cross product points outward.
    """
    rows, cols = points.shape[:2]
    index = np.arange(rows * cols).reshape(rows, cols)
    a, b, c, d = index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]
    faces = np.concatenate(
        [np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)]
    )
    vertices = points.reshape(-1, 3).astype(np.float64)
    welded = weld(vertices)[faces]
    keep = (
        (welded[:, 0] != welded[:, 1])
        & (welded[:, 1] != welded[:, 2])
        & (welded[:, 2] != welded[:, 0])
    )
    faces = faces[keep]
    return TriangleMesh(
        vertices,
        faces.astype(np.int64),
        uvs.reshape(-1, 2).astype(np.float64),
        vertex_normals(vertices, faces),
    )


def _sphere_directions(resolution: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit directions (resolution+1, 2·resolution+1, 3) on a latitude-longitude grid and their
    uvs."""
    theta = np.linspace(0.0, np.pi, resolution + 1)
    phi = np.linspace(0.0, 2.0 * np.pi, 2 * resolution + 1)
    T, P = np.meshgrid(theta, phi, indexing="ij")
    sin_t = portable.sin(T)
    directions = np.stack(
        [sin_t * portable.cos(P), sin_t * portable.sin(P), portable.cos(T)], axis=-1
    )
    directions[:, -1] = directions[:, 0]  # exact seam, so welding finds it
    directions[0, :] = (0.0, 0.0, 1.0)
    directions[-1, :] = (0.0, 0.0, -1.0)
    return directions, np.stack([P / (2.0 * np.pi), 1.0 - T / np.pi], axis=-1)


def sphere(resolution: int = 48) -> TriangleMesh:
    """Unit sphere; ``resolution`` latitude bands."""
    directions, uvs = _sphere_directions(resolution)
    return _grid_mesh(directions, uvs)


def blob(resolution: int = 64, amplitude: float = 0.18, seed: int = 3) -> TriangleMesh:
    """A star-shaped blob: the unit sphere displaced along its normal by a smooth random field
    (a sum of a few low-frequency spherical sinusoids, deterministic in ``seed``)."""
    directions, uvs = _sphere_directions(resolution)
    rng = np.random.default_rng(seed)
    radius = np.ones(directions.shape[:2])
    for _ in range(6):
        axis = rng.normal(size=3)
        axis /= portable.norm(axis)
        frequency = rng.uniform(1.5, 3.5)
        phase = rng.uniform(0, 2 * np.pi)
        radius += (
            amplitude
            / 3.0
            * portable.sin(frequency * np.pi * portable.dot(directions, axis) + phase)
        )
    return _grid_mesh(directions * radius[..., None], uvs)


def rounded_box(
    resolution: int = 64,
    half_extents: tuple[float, float, float] = (1.0, 0.8, 0.6),
    corner_radius: float = 0.25,
) -> TriangleMesh:
    """A box with rounded edges and corners: the zero set of its signed distance, found along each
    direction of a sphere grid by bisection (the shape is star-shaped about its centre)."""
    directions, uvs = _sphere_directions(resolution)
    inner = np.asarray(half_extents, dtype=np.float64) - corner_radius
    if np.any(inner < 0) or corner_radius <= 0:
        raise ValueError(
            f"corner_radius {corner_radius} must be > 0 and ≤ every half extent {half_extents}"
        )

    def signed_distance(points: np.ndarray) -> np.ndarray:
        outside = np.maximum(np.abs(points) - inner, 0.0)
        return (
            portable.norm(outside)
            + np.minimum(np.max(np.abs(points) - inner, axis=-1), 0.0)
            - corner_radius
        )

    low = np.zeros(directions.shape[:2])
    high = np.full(
        directions.shape[:2], float(portable.norm(np.asarray(half_extents, dtype=np.float64))) + 1.0
    )
    for _ in range(60):
        middle = 0.5 * (low + high)
        inside = signed_distance(directions * middle[..., None]) < 0
        low, high = np.where(inside, middle, low), np.where(inside, high, middle)
    return _grid_mesh(directions * (0.5 * (low + high))[..., None], uvs)


def torus(resolution: int = 48, major: float = 1.0, minor: float = 0.45) -> TriangleMesh:
    """A torus around the z axis; u runs along the major circle (the anisotropy direction of a
    brushed-metal BSDF), v around the tube."""
    u = np.linspace(0.0, 2.0 * np.pi, 2 * resolution + 1)
    v = np.linspace(0.0, 2.0 * np.pi, resolution + 1)
    V, U = np.meshgrid(v, u, indexing="ij")
    ring = major + minor * portable.cos(V)
    points = np.stack(
        [ring * portable.cos(U), ring * portable.sin(U), minor * portable.sin(V)], axis=-1
    )
    points[:, -1] = points[:, 0]
    points[-1, :] = points[0, :]
    # rows reversed so that d(row) × d(col) points out of the tube
    return _grid_mesh(points[::-1], np.stack([U / (2 * np.pi), V / (2 * np.pi)], axis=-1)[::-1])


PROCEDURAL_SHAPES = {"sphere": sphere, "blob": blob, "rounded_box": rounded_box, "torus": torus}


def procedural_mesh(name: str) -> TriangleMesh:
    """One of `PROCEDURAL_SHAPES` by name."""
    if name not in PROCEDURAL_SHAPES:
        raise ValueError(
            f"unknown shape {name!r}; expected one of {', '.join(PROCEDURAL_SHAPES)} or a mesh file"
        )
    return PROCEDURAL_SHAPES[name]()


def spherical_uvs(vertices: np.ndarray) -> np.ndarray:
    """Latitude-longitude texture coordinates (V, 2) of vertices about their bounding-box centre."""
    centred = vertices - 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    direction = centred / np.maximum(portable.norm(centred, keepdims=True), 1e-12)
    u = (portable.arctan2(direction[:, 1], direction[:, 0]) / (2 * np.pi)) % 1.0
    v = 1.0 - portable.arccos(np.clip(direction[:, 2], -1.0, 1.0)) / np.pi
    return np.stack([u, v], axis=1)


def mesh_from_arrays(
    vertices: np.ndarray, faces: np.ndarray, uvs: np.ndarray | None = None
) -> TriangleMesh:
    """A `TriangleMesh` from user arrays; missing uvs become `spherical_uvs`, normals are
    recomputed."""
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(faces) == 0 or faces.min() < 0 or faces.max() >= len(vertices):
        raise ValueError(
            f"faces index outside the {len(vertices)} vertices (or the mesh has no faces)"
        )
    uvs = (
        spherical_uvs(vertices)
        if uvs is None or len(uvs) != len(vertices)
        else np.asarray(uvs, np.float64)
    )
    return TriangleMesh(vertices, faces, uvs.reshape(-1, 2), vertex_normals(vertices, faces))


def place_on_ground(mesh: TriangleMesh, lift: float = 1e-3) -> TriangleMesh:
    """Scale and translate so the bounding sphere has radius 1, is centred on the z axis, and the
    lowest vertex sits ``lift`` above z = 0 (a small gap avoids coplanar faces with the ground)."""
    centre, radius = mesh.bounding_sphere()
    vertices = (mesh.vertices - centre) / radius
    vertices[:, 2] += lift - vertices[:, 2].min()
    return TriangleMesh(vertices, mesh.faces, mesh.uvs, mesh.normals)


def load_mesh_file(path: Path) -> TriangleMesh:
    """Read a PLY or OBJ file with Mitsuba's own loaders (needs ``olatbench[synth]``)."""
    from olatbench.datasets.synth.backend import read_mesh_file

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: mesh file not found")
    if path.suffix.lower() not in (".ply", ".obj"):
        raise ValueError(f"{path}: expected a .ply or .obj mesh")
    vertices, faces, uvs = read_mesh_file(path)
    return mesh_from_arrays(vertices, faces, uvs)
