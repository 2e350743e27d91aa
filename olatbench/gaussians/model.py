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


def points_in_ball(n: int, radius: float, seed: int, center: tuple[float, float, float] = (0.0, 0.0, 0.0)
                   ) -> torch.Tensor:
    """(n, 3) float32 CPU points uniform in the ball of ``radius`` around ``center`` (world units), drawn on the CPU
    from ``seed``: the same points on every device and machine."""
    generator = torch.Generator().manual_seed(seed)
    cpu64 = dict(generator=generator, dtype=torch.float64, device="cpu")
    direction = torch.randn(n, 3, **cpu64)
    direction /= direction.norm(dim=1, keepdim=True).clamp_min(1e-12)
    r = radius * torch.rand(n, 1, **cpu64) ** (1.0 / 3.0)
    return (direction * r + torch.tensor(center, dtype=torch.float64, device="cpu")).float()

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
        means = torch.as_tensor(np.asarray(points), device="cpu") if isinstance(points, np.ndarray) else points
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
            rgb = torch.as_tensor(np.asarray(colours), device="cpu") if isinstance(colours, np.ndarray) else colours
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
        points = points_in_ball(n, radius, seed, center)
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
        lo = torch.tensor(low, dtype=torch.float64, device="cpu")
        hi = torch.tensor(high, dtype=torch.float64, device="cpu")
        if not bool((hi > lo).all()):
            raise ValueError(f"random_in_box needs high > low per axis, got low={low}, high={high}")
        points = (lo + (hi - lo) * torch.rand(n, 3, generator=generator, dtype=torch.float64, device="cpu")).float()
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
    binned in a uniform grid and each query looks at the 27 cells around its own, which is exact whenever its
    k-th distance is at most the cell size. Every query starts at a cell size estimated from a sample; a query
    whose k-th neighbour lies farther than the cell size retries with a doubled cell, one whose 27 cells hold
    too many points (a dense cluster) retries with a halved cell, and a query that would reverse direction is
    solved by brute force.
    """
    n = points.shape[0]
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must be (N, 3), got {tuple(points.shape)}")
    if not 0 < k < n:
        raise ValueError(f"need 0 < k < N for the neighbour search, got k={k}, N={n}")
    pts = points.detach().float()
    if not bool(torch.isfinite(pts).all()):
        raise ValueError("points contain NaN or infinite coordinates")
    device = pts.device
    result = torch.empty(n, k, device=device)
    base = _initial_cell_size(pts, k)
    if not math.isfinite(base):  # all sampled neighbours coincide: no useful grid scale
        return _brute_force_knn(pts, torch.arange(n, device=device), k).mean(1).to(points.dtype)
    lo = pts.min(0).values
    diagonal = float((pts.max(0).values - lo).norm())
    level = torch.zeros(n, dtype=torch.int64, device=device)  # cell = base * 2**level, per query
    direction = torch.zeros(n, dtype=torch.int64, device=device)  # +1 went up, -1 went down, 0 not moved
    pending = torch.arange(n, device=device)
    brute = []
    while pending.numel() > 0:
        current = int(level[pending].min())
        cell = base * 2.0**current
        at_level = pending[level[pending] == current]
        if cell > diagonal or cell < diagonal * 2.0**-_FINEST_GRID_BITS:  # the grid cannot help (any more)
            brute.append(at_level)
            pending = pending[level[pending] != current]
            continue
        sq, exact, crowded = _grid_knn(pts, at_level, k, cell, lo)
        done = exact & ~crowded
        result[at_level[done]] = sq[done]
        up, down = at_level[~exact & ~crowded], at_level[crowded]
        # A reversal, or a cluster that stays crowded at any cell size (many duplicates), goes to brute force.
        stuck = direction[down] > 0
        reversal = torch.cat([up[direction[up] < 0], down[stuck]])
        brute.append(reversal)
        up, down = up[direction[up] >= 0], down[~stuck]
        level[up] += 1
        direction[up] = 1
        level[down] -= 1
        direction[down] = -1
        moved = torch.cat([up, down])
        keep = torch.isin(pending, moved) | (level[pending] != current)
        pending = pending[keep & ~torch.isin(pending, reversal)]
    brute_queries = torch.cat(brute) if brute else torch.empty(0, dtype=torch.int64, device=device)
    if brute_queries.numel() > 0:
        result[brute_queries] = _brute_force_knn(pts, brute_queries, k)
    return result.mean(dim=1).to(points.dtype)


def _initial_cell_size(points: torch.Tensor, k: int) -> float:
    """Starting cell size: the lower quartile of the k-th neighbour distance of a random sample of points."""
    n = points.shape[0]
    generator = torch.Generator().manual_seed(0)
    sample = torch.randperm(n, generator=generator, device="cpu")[: min(n, 64)].to(points.device)
    kth = _brute_force_knn(points, sample, k)[:, -1].sqrt()
    positive = kth[kth > 0]
    if positive.numel() == 0:
        return float("nan")
    return float(torch.quantile(positive, 0.25)) * 1.01


def _brute_force_knn(points: torch.Tensor, queries: torch.Tensor, k: int) -> torch.Tensor:
    """(Q, k) ascending squared distances from ``points[queries]`` to their k nearest other points."""
    n = points.shape[0]
    chunk = max(1, _KNN_PAIR_BUDGET // (4 * n))
    out = []
    for start in range(0, queries.numel(), chunk):
        q = queries[start : start + chunk]
        diff = points[q, None, :] - points[None, :, :]
        sq = torch.einsum("qnc,qnc->qn", diff, diff)
        sq[torch.arange(q.numel(), device=points.device), q] = float("inf")
        out.append(torch.topk(sq, k, dim=1, largest=False).values)
    return torch.cat(out)


_NEIGHBOUR_OFFSETS = torch.tensor([(i, j, l) for i in (-1, 0, 1) for j in (-1, 0, 1) for l in (-1, 0, 1)], device="cpu")
# A query whose 27 cells hold more candidates than this is sent to a finer grid, down to cells of
# diagonal / 2**_FINEST_GRID_BITS (cell keys must fit in int64; clusters of duplicates end in brute force).
_MAX_CANDIDATES = 2048
_FINEST_GRID_BITS = 20


def _grid_knn(
    points: torch.Tensor, queries: torch.Tensor, k: int, cell: float, lo: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """k-NN among the 27 grid cells around each query.

    Returns (Q, k) ascending squared distances, ``exact`` (Q,) (k-th distance ≤ cell, so nothing outside the
    block can be closer) and ``crowded`` (Q,) (more than ``_MAX_CANDIDATES`` candidates: not searched).
    """
    device = points.device
    cells = torch.floor((points - lo) / cell).long()
    dims = cells.max(0).values + 1
    keys = (cells[:, 0] * dims[1] + cells[:, 1]) * dims[2] + cells[:, 2]
    sorted_keys, order = torch.sort(keys)
    unique_keys, unique_counts = torch.unique_consecutive(sorted_keys, return_counts=True)
    unique_starts = torch.cumsum(unique_counts, 0) - unique_counts

    # The 27 neighbour cells of a query differ from its own key by constant offsets; only the bounds vary.
    offsets = _NEIGHBOUR_OFFSETS.to(device)
    key_offsets = (offsets[:, 0] * dims[1] + offsets[:, 1]) * dims[2] + offsets[:, 2]
    qcells = cells[queries]
    inside = torch.ones(queries.numel(), offsets.shape[0], dtype=torch.bool, device=device)
    for axis in range(3):
        shifted = qcells[:, axis, None] + offsets[None, :, axis]
        inside &= (shifted >= 0) & (shifted < dims[axis])
    nkeys = keys[queries][:, None] + key_offsets[None, :]
    if int(dims.prod()) <= 8 * points.shape[0] + 1024:  # direct lookup table over all cells
        table_counts = torch.zeros(int(dims.prod()), dtype=torch.int64, device=device)
        table_counts[unique_keys] = unique_counts
        table_starts = torch.zeros_like(table_counts)
        table_starts[unique_keys] = unique_starts
        safe = torch.where(inside, nkeys, torch.zeros_like(nkeys))
        start = table_starts[safe]
        counts = torch.where(inside, table_counts[safe], torch.zeros_like(safe))
    else:
        slot = torch.searchsorted(unique_keys, nkeys).clamp_max(unique_keys.numel() - 1)
        start = unique_starts[slot]
        counts = torch.where(inside & (unique_keys[slot] == nkeys), unique_counts[slot], torch.zeros_like(slot))
    per_query = counts.sum(1)
    crowded = per_query > _MAX_CANDIDATES
    counts[crowded] = 0
    per_query[crowded] = 0

    sq_out = torch.full((queries.numel(), k), float("inf"), device=device)
    cumulative = torch.cumsum(per_query, 0)
    first = 0
    while first < queries.numel():
        reached = int(cumulative[first - 1]) if first else 0
        last = int(torch.searchsorted(cumulative, reached + _KNN_PAIR_BUDGET, right=True))
        last = min(max(last, first + 1), queries.numel())
        q_counts = counts[first:last].reshape(-1)
        total = int(q_counts.sum())
        if total > 0:
            seg = torch.repeat_interleave(torch.arange(q_counts.numel(), device=device), q_counts)
            within = torch.arange(total, device=device) - (torch.cumsum(q_counts, 0) - q_counts)[seg]
            candidate = order[start[first:last].reshape(-1)[seg] + within]
            local_query = torch.div(seg, offsets.shape[0], rounding_mode="floor")
            query = queries[first:last][local_query]
            diff = points[candidate] - points[query]
            sq = torch.einsum("pc,pc->p", diff, diff).masked_fill(candidate == query, float("inf"))
            row_counts = per_query[first:last]
            row_first = torch.cumsum(row_counts, 0) - row_counts
            dense = torch.full((last - first, max(int(row_counts.max()), k)), float("inf"), device=device)
            dense[local_query, torch.arange(total, device=device) - row_first[local_query]] = sq
            sq_out[first:last] = torch.topk(dense, k, dim=1, largest=False).values
        first = last
    # Nothing outside the 27-cell block is closer than the distance from the query to the block's boundary.
    position = (points[queries] - lo) / cell - qcells.to(points.dtype)  # in [0, 1) within its own cell
    margin = cell * (1.0 + torch.minimum(position, 1.0 - position).min(1).values.clamp(0.0, 1.0))
    exact = sq_out[:, -1] <= margin * margin
    return sq_out, exact, crowded
