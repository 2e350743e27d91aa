"""Minimal PLY point reader/writer (numpy only): the ``vertex`` element's x, y, z and optional red,
green, blue (the writer also nx, ny, nz).

Reads ``ascii``, ``binary_little_endian`` and ``binary_big_endian`` files. Other elements (faces, …)
are skipped; in binary files an element with list properties can only be skipped when it comes
*after* the vertices (its size is not known in advance). Colours stored as integers are scaled to
[0, 1] by their type's maximum (255 for ``uchar``); float colours are returned as stored.

The counts the header declares are checked before anything is allocated: each at most
`MAX_PLY_ELEMENTS`, and the elements up to the vertices no larger than the bytes after the header
can hold, so a damaged or hostile header is one `PlyError` naming the file, never a ``MemoryError``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from olatbench.atomic import write_bytes
from olatbench.datasets.colour import quantize_8bit

# PLY scalar type names (both spellings) -> numpy type codes without byte order.
_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip
_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
#: The most elements (points, faces, …) one header line may declare: 2³¹ − 1, a 32-bit count, about
#: 100 times the largest point clouds and Gaussian models in use (10⁶–10⁷ points).
MAX_PLY_ELEMENTS = 2**31 - 1


class PlyError(ValueError):
    """A PLY file that cannot be read; the message names the file and the problem."""


@dataclass
class _Element:
    name: str
    count: int
    properties: list[tuple[str, str]] = field(default_factory=list)  # (name, numpy code)
    has_list: bool = False


def _parse_header(path: Path, handle) -> tuple[str, list[_Element]]:
    magic = handle.readline().strip()
    if magic != b"ply":
        raise PlyError(f"{path}: not a PLY file (first line is {magic[:20]!r}, expected b'ply')")
    fmt = None
    elements: list[_Element] = []
    while True:
        raw = handle.readline()
        if not raw:
            raise PlyError(f"{path}: header has no 'end_header' line")
        words = raw.decode("ascii", errors="replace").split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "end_header":
            break
        if words[0] == "format":
            if len(words) < 2 or words[1] not in _FORMATS:
                raise PlyError(f"{path}: unsupported PLY format line {raw!r}")
            fmt = words[1]
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise PlyError(f"{path}: malformed element line {raw!r}")
            elements.append(_Element(words[1], int(words[2])))
        elif words[0] == "property":
            if not elements:
                raise PlyError(f"{path}: property before any element: {raw!r}")
            if len(words) >= 2 and words[1] == "list":
                elements[-1].has_list = True
                elements[-1].properties.append((words[-1], "list"))
            elif len(words) == 3 and words[1] in _PLY_TYPES:
                elements[-1].properties.append((words[2], _PLY_TYPES[words[1]]))
            else:
                raise PlyError(f"{path}: unsupported property line {raw!r}")
    if fmt is None:
        raise PlyError(f"{path}: header has no 'format' line")
    return fmt, elements


def _min_bytes(element: _Element, order: str | None) -> int:
    """The fewest bytes ``element.count`` entries can take: binary, the fixed row size (a list
    property at least its one-byte count); ascii (``order`` None), one character and one separator
    per value."""
    if order is None:
        return element.count * 2 * max(1, len(element.properties))
    fixed = [code for _, code in element.properties if code != "list"]
    row = (
        np.dtype([(f"f{i}", order + code) for i, code in enumerate(fixed)]).itemsize if fixed else 0
    )
    return element.count * (row + (len(element.properties) - len(fixed)))


def _check_counts(
    path: Path, fmt: str, elements: list[_Element], vertex: _Element, available: int
) -> None:
    """Refuse a header whose counts exceed `MAX_PLY_ELEMENTS`, or whose elements up to the vertices
    cannot fit in the ``available`` bytes after it, naming the file, the element and both
    numbers."""
    order = _FORMATS[fmt]
    needed = 0
    for element in elements:
        if element.count > MAX_PLY_ELEMENTS:
            raise PlyError(
                f"{path}: the header declares {element.count:,} '{element.name}' elements, more "
                f"than the {MAX_PLY_ELEMENTS:,} a PLY file read here may hold (a damaged header?)"
            )
        needed += _min_bytes(element, order)
        # ascii: the last value may end the file without a separator
        if needed > available + (order is None):
            raise PlyError(
                f"{path}: the header declares {element.count:,} '{element.name}' elements, which "
                f"take at least {needed:,} bytes, but the file holds {available:,} after its "
                "header (truncated, or a damaged header)"
            )
        if element is vertex:
            return


def _colour_scale(code: str) -> float:
    return float(np.iinfo(np.dtype(code)).max) if code[0] in "iu" else 1.0


def read_ply_points(path: str | Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Vertex positions (N, 3) float32 and colours (N, 3) float32 in [0, 1]
    (``None`` without red/green/blue)."""
    path = Path(path)
    if not path.is_file():
        raise PlyError(f"{path}: no such PLY file")
    with open(path, "rb") as handle:
        fmt, elements = _parse_header(path, handle)
        vertex = next((e for e in elements if e.name == "vertex"), None)
        if vertex is None:
            raise PlyError(f"{path}: no 'vertex' element")
        names = [name for name, _ in vertex.properties]
        missing = [axis for axis in "xyz" if axis not in names]
        if missing:
            raise PlyError(f"{path}: vertex element lacks properties {missing} (has {names})")
        if vertex.has_list:
            raise PlyError(f"{path}: list properties in the vertex element are not supported")
        _check_counts(path, fmt, elements, vertex, path.stat().st_size - handle.tell())
        order = _FORMATS[fmt]
        if order is None:
            table = _read_ascii(path, handle, elements, vertex)
        else:
            table = _read_binary(path, handle, elements, vertex, order)
    types = dict(vertex.properties)
    points = np.stack([table["x"], table["y"], table["z"]], axis=1).astype(np.float32)
    colours = None
    if all(channel in types for channel in ("red", "green", "blue")):
        colours = np.stack(
            [
                table[c].astype(np.float64) / _colour_scale(types[c])
                for c in ("red", "green", "blue")
            ],
            axis=1,
        ).astype(np.float32)
    return points, colours


def _read_ascii(
    path: Path, handle, elements: list[_Element], vertex: _Element
) -> dict[str, np.ndarray]:
    for element in elements:
        if element is vertex:
            break
        for _ in range(element.count):
            handle.readline()
    rows = [handle.readline().split() for _ in range(vertex.count)]
    width = len(vertex.properties)
    bad = next((i for i, row in enumerate(rows) if len(row) < width), None)
    if bad is not None:
        raise PlyError(f"{path}: vertex {bad} has {len(rows[bad])} values, expected {width}")
    try:
        values = np.array([row[:width] for row in rows], dtype=np.float64).reshape(
            vertex.count, width
        )
    except ValueError as error:
        raise PlyError(f"{path}: non-numeric vertex data ({error})") from error
    return {name: values[:, i] for i, (name, _) in enumerate(vertex.properties)}


def _read_binary(
    path: Path, handle, elements: list[_Element], vertex: _Element, order: str
) -> dict[str, np.ndarray]:
    for element in elements:
        if element is vertex:
            break
        if element.has_list:
            raise PlyError(
                f"{path}: cannot skip element '{element.name}' with list properties before the "
                "vertices"
            )
        handle.seek(
            element.count * np.dtype([(n, order + c) for n, c in element.properties]).itemsize, 1
        )
    dtype = np.dtype([(name, order + code) for name, code in vertex.properties])
    data = handle.read(dtype.itemsize * vertex.count)
    if len(data) != dtype.itemsize * vertex.count:
        raise PlyError(
            f"{path}: truncated vertex data ({len(data)} of {dtype.itemsize * vertex.count} bytes)"
        )
    table = np.frombuffer(data, dtype=dtype, count=vertex.count)
    return {name: table[name] for name in dtype.names}


def write_ply_points(
    path: str | Path,
    points: np.ndarray,
    colours: np.ndarray | None = None,
    normals: np.ndarray | None = None,
) -> Path:
    """Write points (N, 3) (+ ``normals`` (N, 3) as float ``nx ny nz``, + ``colours`` (N, 3) in
    [0, 1] as uchar) as binary little-endian PLY, atomically; properties in the order x y z nx ny nz
    red green blue, as the 3DGS loaders' ``storePly`` writes them."""
    points = np.asarray(points, dtype=np.float32)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must be (N, 3), got {points.shape}")
    columns: list[tuple[str, str, np.ndarray]] = [
        (axis, "float", points[:, i]) for i, axis in enumerate("xyz")
    ]
    for name, values, kind in (("normals", normals, "float"), ("colours", colours, "uchar")):
        if values is None:
            continue
        values = np.asarray(values, dtype=np.float64)
        if values.shape != points.shape:
            raise ValueError(f"{name} must be {points.shape}, got {values.shape}")
        if kind == "uchar":
            values = quantize_8bit(values)
        labels = ("nx", "ny", "nz") if name == "normals" else ("red", "green", "blue")
        columns += [(label, kind, values[:, i]) for i, label in enumerate(labels)]
    codes = {"float": "<f4", "uchar": "u1"}
    table = np.empty(
        len(points), dtype=np.dtype([(label, codes[kind]) for label, kind, _ in columns])
    )
    for label, _, values in columns:
        table[label] = values
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(points)}"]
    header += [f"property {kind} {label}" for label, kind, _ in columns]
    header.append("end_header")
    return write_bytes(path, ("\n".join(header) + "\n").encode("ascii") + table.tobytes())


__all__ = ["PlyError", "read_ply_points", "write_ply_points"]
