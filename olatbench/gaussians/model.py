"""The Gaussian parameter container shared by every method.

A :class:`GaussianModel` holds N anisotropic 3D Gaussians as raw (unconstrained) parameters:

- ``means`` (N, 3) world-space centres,
- ``log_scales`` (N, 3) natural logs of the per-axis standard deviations (``scales = exp(log_scales)``),
- ``quats`` (N, 4) rotations as ``wxyz`` quaternions, unnormalised (renderers normalise),
- ``opacity_logits`` (N,) with ``opacities = sigmoid(opacity_logits)``,
- ``attributes``: any named per-Gaussian tensors (N, ...) a method needs (albedo, latent material, …), stored
  raw; activations are the method's business.

Every parameter's first dimension is N; :mod:`olatbench.gaussians.optim` relies on that to keep optimizer state
aligned when Gaussians are added or removed. Initialisation follows 3DGS: opacity 0.1, identity rotation,
isotropic scale = sqrt(mean squared distance to the 3 nearest neighbours) (``distCUDA2``), computed here with an
exact grid search that needs no CUDA extension.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from olatbench.atomic import atomic_path

CHECKPOINT_FORMAT = "olatbench.gaussians.GaussianModel/1"
CORE_PARAMETERS = ("means", "log_scales", "quats", "opacity_logits")
# Trailing shapes of the core parameters (after the leading N).
_CORE_SHAPES = {"means": (3,), "log_scales": (3,), "quats": (4,), "opacity_logits": ()}
# 3DGS clamps the squared neighbour distance from below so that duplicate points get a finite log-scale.
MIN_NEIGHBOUR_SQ_DISTANCE = 1e-7
# Budget (number of candidate pairs) per chunk of the nearest-neighbour search.
_KNN_PAIR_BUDGET = 1 << 22

AttributeSpec = tuple[int, ...] | torch.Tensor


class GaussianModel(nn.Module):
    """N 3D Gaussians as ``nn.Parameter`` tensors whose first dimension is N (see the module docstring)."""

    def __init__(
        self,
        means: torch.Tensor,
        log_scales: torch.Tensor,
        quats: torch.Tensor,
        opacity_logits: torch.Tensor,
        attributes: dict[str, torch.Tensor] | None = None,
    ) -> None:
        super().__init__()
        n = means.shape[0]
        values = {"means": means, "log_scales": log_scales, "quats": quats, "opacity_logits": opacity_logits}
        for name, value in values.items():
            _check_rows(name, value, n, _CORE_SHAPES[name])
            setattr(self, name, nn.Parameter(value.detach().clone()))
        self.attributes = nn.ParameterDict()
        for name, value in (attributes or {}).items():
            _check_rows(f"attributes[{name!r}]", value, n, None)
            self.attributes[name] = nn.Parameter(value.detach().clone())

    # ----------------------------------------------------------------------------------------- activations
    @property
    def scales(self) -> torch.Tensor:
        """(N, 3) linear standard deviations ``exp(log_scales)``."""
        return torch.exp(self.log_scales)

    @property
    def opacities(self) -> torch.Tensor:
        """(N,) opacities in (0, 1): ``sigmoid(opacity_logits)``."""
        return torch.sigmoid(self.opacity_logits)

    @property
    def num_gaussians(self) -> int:
        return int(self.means.shape[0])

    def per_gaussian_parameters(self) -> dict[str, nn.Parameter]:
        """Every per-Gaussian parameter by name (``means`` …, ``attributes.<name>``), in a stable order."""
        params = {name: getattr(self, name) for name in CORE_PARAMETERS}
        params.update({f"attributes.{name}": value for name, value in self.attributes.items()})
        return params

    # -------------------------------------------------------------------------------------- constructors
    @classmethod
    def from_points(
        cls,
        points: torch.Tensor | np.ndarray,
        colours: torch.Tensor | np.ndarray | None = None,
        attributes: dict[str, AttributeSpec] | None = None,
        opacity: float = 0.1,
        device: torch.device | str | None = None,
        dtype: torch.dtype = torch.float32,
    ) -> GaussianModel:
        """Gaussians centred on ``points`` (N, 3), 3DGS-initialised (see the module docstring).

        ``colours`` (N, 3), if given, becomes the attribute ``"colour"``. ``attributes`` maps names to either a
        trailing shape (zeros of shape (N, *shape)) or a tensor (N, ...) used as is.
        """
        means = torch.as_tensor(np.asarray(points) if isinstance(points, np.ndarray) else points)
        means = means.to(device=device, dtype=dtype)
        if means.ndim != 2 or means.shape[1] != 3 or means.shape[0] == 0:
            raise ValueError(f"points must be a non-empty (N, 3) array, got shape {tuple(means.shape)}")
        if not bool(torch.isfinite(means).all()):
            raise ValueError("points contain NaN or infinite coordinates")
        n = means.shape[0]
        if n > 1:
            sq = mean_neighbour_sq_distance(means, k=min(3, n - 1))
        else:
            sq = torch.ones(1, device=means.device, dtype=dtype)
        log_scales = 0.5 * torch.log(sq.clamp_min(MIN_NEIGHBOUR_SQ_DISTANCE))[:, None].repeat(1, 3)
        quats = torch.zeros(n, 4, device=means.device, dtype=dtype)
        quats[:, 0] = 1.0
        if not 0.0 < opacity < 1.0:
            raise ValueError(f"initial opacity must be in (0, 1), got {opacity}")
        opacity_logits = torch.full((n,), math.log(opacity / (1.0 - opacity)), device=means.device, dtype=dtype)
        values = _build_attributes(attributes, n, means.device, dtype)
        if colours is not None:
            rgb = torch.as_tensor(np.asarray(colours) if isinstance(colours, np.ndarray) else colours)
            rgb = rgb.to(device=means.device, dtype=dtype)
            _check_rows("colours", rgb, n, (3,))
            values["colour"] = rgb
        return cls(means, log_scales, quats, opacity_logits, values)

    @classmethod
    def random_in_sphere(
        cls,
        n: int,
        radius: float = 1.0,
        attributes: dict[str, AttributeSpec] | None = None,
        seed: int = 0,
        device: torch.device | str | None = None,
        center: tuple[float, float, float] = (0.0, 0.0, 0.0),
        opacity: float = 0.1,
    ) -> GaussianModel:
        """``n`` Gaussians uniform in the ball of ``radius`` around ``center`` (SSD-GS: 10K in the unit ball)."""
        generator = torch.Generator().manual_seed(seed)
        direction = torch.randn(n, 3, generator=generator, dtype=torch.float64)
        direction /= direction.norm(dim=1, keepdim=True).clamp_min(1e-12)
        r = radius * torch.rand(n, 1, generator=generator, dtype=torch.float64) ** (1.0 / 3.0)
        points = (direction * r + torch.tensor(center, dtype=torch.float64)).float()
        return cls.from_points(points, attributes=attributes, opacity=opacity, device=device)

    @classmethod
    def random_in_box(
        cls,
        n: int,
        low: tuple[float, float, float] = (-0.5, -0.5, -0.5),
        high: tuple[float, float, float] = (0.5, 0.5, 0.5),
        attributes: dict[str, AttributeSpec] | None = None,
        seed: int = 0,
        device: torch.device | str | None = None,
        opacity: float = 0.1,
    ) -> GaussianModel:
        """``n`` Gaussians uniform in the axis-aligned box [low, high] (3DGS Blender / SSD-GS code: 100K in ±0.5)."""
        generator = torch.Generator().manual_seed(seed)
        lo = torch.tensor(low, dtype=torch.float64)
        hi = torch.tensor(high, dtype=torch.float64)
        if not bool((hi > lo).all()):
            raise ValueError(f"random_in_box needs high > low per axis, got low={low}, high={high}")
        points = (lo + (hi - lo) * torch.rand(n, 3, generator=generator, dtype=torch.float64)).float()
        return cls.from_points(points, attributes=attributes, opacity=opacity, device=device)

    @classmethod
    def from_ply(
        cls,
        path: str | Path,
        attributes: dict[str, AttributeSpec] | None = None,
        device: torch.device | str | None = None,
        opacity: float = 0.1,
    ) -> GaussianModel:
        """Gaussians on the vertices of a point PLY (x, y, z and optional red, green, blue -> ``"colour"``)."""
        from olatbench.gaussians.ply import read_ply_points

        points, colours = read_ply_points(path)
        if len(points) == 0:
            raise ValueError(f"{path}: the PLY file has no vertices")
        return cls.from_points(points, colours=colours, attributes=attributes, opacity=opacity, device=device)

    # -------------------------------------------------------------------------------------- persistence
    def to_dict(self) -> dict[str, Any]:
        """Plain dict of detached tensors and strings (what :meth:`save` writes)."""
        return {
            "format": CHECKPOINT_FORMAT,
            **{name: getattr(self, name).detach() for name in CORE_PARAMETERS},
            "attributes": {name: value.detach() for name, value in self.attributes.items()},
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "checkpoint") -> GaussianModel:
        """Inverse of :meth:`to_dict`; ``source`` names the origin in error messages."""
        if not isinstance(data, dict) or data.get("format") != CHECKPOINT_FORMAT:
            found = data.get("format") if isinstance(data, dict) else type(data).__name__
            raise ValueError(f"{source}: not a GaussianModel checkpoint (format {found!r}, need {CHECKPOINT_FORMAT!r})")
        missing = [name for name in (*CORE_PARAMETERS, "attributes") if name not in data]
        if missing:
            raise ValueError(f"{source}: missing fields {missing}")
        for name in CORE_PARAMETERS:
            if not isinstance(data[name], torch.Tensor):
                raise ValueError(f"{source}: field {name!r} is not a tensor")
        if not isinstance(data["attributes"], dict):
            raise ValueError(f"{source}: field 'attributes' is not a dict")
        try:
            return cls(*(data[name] for name in CORE_PARAMETERS), attributes=data["attributes"])
        except ValueError as error:
            raise ValueError(f"{source}: {error}") from error

    def save(self, path: str | Path) -> Path:
        """Write the Gaussians to ``path`` atomically (``torch.save`` of tensors and strings only)."""
        path = Path(path)
        data = self.to_dict()
        data = {k: (v.cpu() if isinstance(v, torch.Tensor) else v) for k, v in data.items()}
        data["attributes"] = {k: v.cpu() for k, v in data["attributes"].items()}
        with atomic_path(path) as temporary:
            torch.save(data, temporary)
        return path

    @classmethod
    def load(cls, path: str | Path, device: torch.device | str | None = None) -> GaussianModel:
        """Read a file written by :meth:`save` (``torch.load(weights_only=True)``) onto ``device``."""
        path = Path(path)
        try:
            data = torch.load(path, map_location=device or "cpu", weights_only=True)
        except FileNotFoundError as error:
            raise FileNotFoundError(f"{path}: no such Gaussian checkpoint") from error
        except Exception as error:  # corrupt files raise many different unpickling errors
            raise ValueError(f"{path}: cannot read Gaussian checkpoint ({error})") from error
        return cls.from_dict(data, source=str(path))

    def _load_from_state_dict(self, state_dict, prefix, local_metadata, strict, missing_keys, unexpected_keys,
                              error_msgs):  # fmt: skip
        """Let ``load_state_dict`` change N and add attributes (a checkpoint usually has a different count).

        Parameters keep their identity (``.data`` is replaced), so an optimizer built on this model stays valid.
        """
        for name in CORE_PARAMETERS:
            key = prefix + name
            if key in state_dict and state_dict[key].shape != getattr(self, name).shape:
                param = getattr(self, name)
                param.data = torch.empty_like(state_dict[key], device=param.device, dtype=param.dtype)
        attribute_prefix = prefix + "attributes."
        for key, value in state_dict.items():
            name = key[len(attribute_prefix):]
            if not key.startswith(attribute_prefix) or "." in name:
                continue
            if name not in self.attributes:
                self.attributes[name] = nn.Parameter(torch.empty_like(value, device=self.means.device))
            elif self.attributes[name].shape != value.shape:
                param = self.attributes[name]
                param.data = torch.empty_like(value, device=param.device, dtype=param.dtype)
        super()._load_from_state_dict(
            state_dict, prefix, local_metadata, strict, missing_keys, unexpected_keys, error_msgs
        )


def _check_rows(name: str, value: torch.Tensor, n: int, trailing: tuple[int, ...] | None) -> None:
    if not isinstance(value, torch.Tensor):
        raise ValueError(f"{name} must be a tensor, got {type(value).__name__}")
    if value.ndim == 0 or value.shape[0] != n:
        raise ValueError(f"{name} must have {n} rows (one per Gaussian), got shape {tuple(value.shape)}")
    if trailing is not None and tuple(value.shape[1:]) != trailing:
        raise ValueError(f"{name} must have shape (N, {', '.join(map(str, trailing))}), got {tuple(value.shape)}")


def _build_attributes(
    specs: dict[str, AttributeSpec] | None, n: int, device: torch.device, dtype: torch.dtype
) -> dict[str, torch.Tensor]:
    values = {}
    for name, spec in (specs or {}).items():
        if isinstance(spec, torch.Tensor):
            _check_rows(f"attributes[{name!r}]", spec, n, None)
            values[name] = spec.to(device=device)
        else:
            values[name] = torch.zeros((n, *tuple(spec)), device=device, dtype=dtype)
    return values


# ----------------------------------------------------------------------------------- nearest neighbours
def mean_neighbour_sq_distance(points: torch.Tensor, k: int = 3) -> torch.Tensor:
    """(N,) mean squared Euclidean distance from each point to its ``k`` nearest *other* points (exact).

    This is what 3DGS's ``distCUDA2`` returns for k = 3. Works on any device without a KD-tree: points are
    binned in a uniform grid whose cell size is estimated from a sample; each query looks at the 27 cells around
    it, which is exact whenever its k-th distance is at most the cell size. Queries that fail this test are
    retried with a doubled cell size (the last resort is a chunked brute-force search).
    """
    n = points.shape[0]
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must be (N, 3), got {tuple(points.shape)}")
    if not 0 < k < n:
        raise ValueError(f"need 0 < k < N for the neighbour search, got k={k}, N={n}")
    pts = points.detach()
    work = pts.double() if pts.device.type == "cpu" else pts.float()
    result = torch.empty(n, k, device=pts.device, dtype=work.dtype)
    pending = torch.arange(n, device=pts.device)
    lo, hi = work.min(0).values, work.max(0).values
    diagonal = float((hi - lo).norm())
    cell = _initial_cell_size(work, k)
    while pending.numel() > 0:
        if not diagonal > 0 or cell > diagonal or not math.isfinite(cell):
            result[pending] = _brute_force_knn(work, pending, k)
            break
        sq, exact = _grid_knn(work, pending, k, cell, lo)
        result[pending[exact]] = sq[exact]
        pending = pending[~exact]
        cell *= 2.0
    return result.mean(dim=1).to(points.dtype)


def _initial_cell_size(points: torch.Tensor, k: int) -> float:
    """Cell size ≈ the 90th percentile of the k-th neighbour distance of a random sample of points."""
    n = points.shape[0]
    generator = torch.Generator().manual_seed(0)
    sample = torch.randperm(n, generator=generator)[: min(n, 256)].to(points.device)
    kth = _brute_force_knn(points, sample, k)[:, -1].sqrt()
    positive = kth[kth > 0]
    if positive.numel() == 0:
        return float("nan")  # degenerate (duplicates): the brute force handles it
    return float(torch.quantile(positive, 0.9)) * 1.01


def _brute_force_knn(points: torch.Tensor, queries: torch.Tensor, k: int) -> torch.Tensor:
    """(Q, k) ascending squared distances from ``points[queries]`` to their k nearest other points."""
    n = points.shape[0]
    chunk = max(1, _KNN_PAIR_BUDGET // n)
    out = []
    for start in range(0, queries.numel(), chunk):
        q = queries[start : start + chunk]
        sq = ((points[q, None, :] - points[None, :, :]) ** 2).sum(-1)
        sq[torch.arange(q.numel(), device=points.device), q] = float("inf")
        out.append(torch.topk(sq, k, dim=1, largest=False).values)
    return torch.cat(out)


_NEIGHBOUR_OFFSETS = torch.tensor([(i, j, l) for i in (-1, 0, 1) for j in (-1, 0, 1) for l in (-1, 0, 1)])


def _grid_knn(
    points: torch.Tensor, queries: torch.Tensor, k: int, cell: float, lo: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """k-NN among the 27 grid cells around each query; returns (Q, k) squared distances and an exactness mask."""
    device = points.device
    cells = torch.floor((points - lo) / cell).long()
    dims = cells.max(0).values + 1
    keys = (cells[:, 0] * dims[1] + cells[:, 1]) * dims[2] + cells[:, 2]
    sorted_keys, order = torch.sort(keys)
    offsets = _NEIGHBOUR_OFFSETS.to(device)
    sq_out = torch.full((queries.numel(), k), float("inf"), device=device, dtype=points.dtype)

    # Candidate ranges [start, end) in the sorted order for each (query, neighbour cell).
    neighbour = cells[queries][:, None, :] + offsets[None]  # (Q, 27, 3)
    inside = ((neighbour >= 0) & (neighbour < dims)).all(-1)
    nkeys = (neighbour[..., 0] * dims[1] + neighbour[..., 1]) * dims[2] + neighbour[..., 2]
    start = torch.searchsorted(sorted_keys, nkeys, right=False)
    end = torch.searchsorted(sorted_keys, nkeys, right=True)
    counts = torch.where(inside, end - start, torch.zeros_like(start))
    per_query = counts.sum(1)

    # Process queries in chunks with a bounded number of candidate pairs.
    bounds = torch.cumsum(per_query, 0)
    first = 0
    while first < queries.numel():
        budget_end = int(torch.searchsorted(bounds, (bounds[first - 1] if first else 0) + _KNN_PAIR_BUDGET))
        last = max(first + 1, min(budget_end, queries.numel()))
        q_counts = counts[first:last].reshape(-1)
        q_start = start[first:last].reshape(-1)
        total = int(q_counts.sum())
        seg = torch.repeat_interleave(torch.arange(q_counts.numel(), device=device), q_counts)
        seg_first = torch.cumsum(q_counts, 0) - q_counts
        candidate = order[q_start[seg] + torch.arange(total, device=device) - seg_first[seg]]
        local_query = seg // offsets.shape[0]
        query = queries[first:last][local_query]
        sq = ((points[candidate] - points[query]) ** 2).sum(-1)
        sq = torch.where(candidate == query, torch.full_like(sq, float("inf")), sq)
        # Dense (Q_chunk, max_candidates) table padded with inf, then top-k per row.
        row_counts = per_query[first:last]
        width = max(int(row_counts.max()), k)
        row_first = torch.cumsum(row_counts, 0) - row_counts
        dense = torch.full((last - first, width), float("inf"), device=device, dtype=points.dtype)
        dense[local_query, torch.arange(total, device=device) - row_first[local_query]] = sq
        sq_out[first:last] = torch.topk(dense, k, dim=1, largest=False).values
        first = last
    exact = sq_out[:, -1] <= cell * cell
    return sq_out, exact

