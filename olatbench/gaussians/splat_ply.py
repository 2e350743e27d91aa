"""Trained Gaussians as a PLY file in the layout of the original 3D Gaussian Splatting, which splat
viewers and editors that read properties by name open (SuperSplat, the original code's ``load_ply``,
gsplat's and nerfstudio's importers; SIBR's viewer reads a fixed record and so rejects the extra
properties).

One binary little-endian ``vertex`` element, every property ``float``, in this order:

- ``x y z``: the centre;
- ``nx ny nz``: zeros (3DGS writes them; viewers ignore them);
- ``f_dc_0..2``: the degree-0 spherical-harmonic coefficient of red, green, blue (colour ``0.5 + C0
  · f_dc``, ``C0 = 1 / (2√π)``);
- ``f_rest_0..3R-1``: the higher-degree coefficients, channel-major as 3DGS stores them
  (``f_rest_{c·R + k}`` is coefficient ``k + 1`` of channel ``c``; R = 0 for a colour without view
  dependence);
- ``opacity``: the logit of the opacity (viewers apply a sigmoid);
- ``scale_0..2``: the natural logs of the per-axis standard deviations (viewers apply exp);
- ``rot_0..3``: the rotation quaternion ``w x y z``, as trained (viewers normalise);
- then the method's other per-Gaussian attributes, ``<name>_<i>`` for each column of an (N, k)
  attribute (the raw stored values; the method decides their activation).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from olatbench.atomic import write_bytes


@dataclass
class SplatCloud:
    """N Gaussians to write: ``means`` (N, 3), ``log_scales`` (N, 3), ``quats`` (N, 4) wxyz,
    ``opacity_logits`` (N,), ``sh_dc`` (N, 3), ``sh_rest`` (N, R, 3) with R ≥ 0, ``extras`` name ->
    (N, k) or (N,) raw attributes; ``comments`` go into the header (one line each)."""

    means: np.ndarray
    log_scales: np.ndarray
    quats: np.ndarray
    opacity_logits: np.ndarray
    sh_dc: np.ndarray
    sh_rest: np.ndarray
    extras: Mapping[str, np.ndarray] = field(default_factory=dict)
    comments: Sequence[str] = ()

    def columns(self) -> list[tuple[str, np.ndarray]]:
        """(property name, (N,) float32 column) in file order; a `ValueError` names a mis-shaped
        array."""
        n = len(self.means)
        shapes = {
            "means": (n, 3),
            "log_scales": (n, 3),
            "quats": (n, 4),
            "opacity_logits": (n,),
            "sh_dc": (n, 3),
        }
        for name, shape in shapes.items():
            if np.shape(getattr(self, name)) != shape:
                raise ValueError(f"{name} must be {shape}, got {np.shape(getattr(self, name))}")
        rest = np.asarray(self.sh_rest, dtype=np.float32)
        if rest.ndim != 3 or rest.shape[0] != n or rest.shape[2] != 3:
            raise ValueError(f"sh_rest must be (N={n}, R, 3), got {rest.shape}")
        columns = [(axis, self.means[:, i]) for i, axis in enumerate("xyz")]
        columns += [(name, np.zeros(n, np.float32)) for name in ("nx", "ny", "nz")]
        columns += [(f"f_dc_{c}", self.sh_dc[:, c]) for c in range(3)]
        # (N, 3·R): all of red's, then green's, then blue's
        channel_major = rest.transpose(0, 2, 1).reshape(n, -1)
        columns += [(f"f_rest_{j}", channel_major[:, j]) for j in range(channel_major.shape[1])]
        columns.append(("opacity", self.opacity_logits))
        columns += [(f"scale_{i}", self.log_scales[:, i]) for i in range(3)]
        columns += [(f"rot_{i}", self.quats[:, i]) for i in range(4)]
        taken = {name for name, _ in columns}
        for name, values in self.extras.items():
            table = np.asarray(values).reshape(n, -1)
            for i in range(table.shape[1]):
                prop = f"{name}_{i}"
                if prop in taken or not (prop.isascii() and prop.replace("_", "").isalnum()):
                    raise ValueError(
                        f"extra attribute {name!r} gives the property name {prop!r}, which is "
                        "taken or not a plain word"
                    )
                taken.add(prop)
                columns.append((prop, table[:, i]))
        return [(name, np.asarray(column, dtype=np.float32)) for name, column in columns]


def write_splat_ply(path: str | Path, cloud: SplatCloud) -> Path:
    """Write ``cloud`` to ``path`` in the 3DGS layout (module docstring), atomically; returns the
    path."""
    columns = cloud.columns()
    table = np.empty(len(cloud.means), dtype=np.dtype([(name, "<f4") for name, _ in columns]))
    for name, column in columns:
        table[name] = column
    header = ["ply", "format binary_little_endian 1.0"]
    header += [f"comment {line}" for text in cloud.comments for line in text.splitlines()]
    header.append(f"element vertex {len(table)}")
    header += [f"property float {name}" for name, _ in columns]
    header.append("end_header")
    # PLY headers are ASCII: other characters of comments are escaped
    text = "\n".join(header) + "\n"
    return write_bytes(path, text.encode("ascii", "backslashreplace") + table.tobytes())


__all__ = ["SplatCloud", "write_splat_ply"]
