"""Exact k-nearest-neighbour distances of a point cloud on any device, without a KD-tree or CUDA
extension: `mean_neighbour_sq_distance`, what 3DGS's ``distCUDA2`` returns, for the initial scales
of `GaussianModel`.
"""

from __future__ import annotations

import math

import torch

# Budget (number of candidate pairs) per chunk of the nearest-neighbour search.
_KNN_PAIR_BUDGET = 1 << 22


def mean_neighbour_sq_distance(points: torch.Tensor, k: int = 3) -> torch.Tensor:
    """(N,) mean squared Euclidean distance from each point to its ``k`` nearest *other* points
    (exact).

    This is what 3DGS's ``distCUDA2`` returns for k = 3. Works on any device without a KD-tree:
    points are binned in a uniform grid and each query looks at the 27 cells around its own, which
    is exact whenever its k-th distance is at most the cell size. Every query starts at a cell size
    estimated from a sample; a query whose k-th neighbour lies farther than the cell size retries
    with a doubled cell, one whose 27 cells hold too many points (a dense cluster) retries with a
    halved cell, and a query that would reverse direction is solved by brute force.
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
    # +1 went up, -1 went down, 0 not moved
    direction = torch.zeros(n, dtype=torch.int64, device=device)
    pending = torch.arange(n, device=device)
    brute = []
    while pending.numel() > 0:
        current = int(level[pending].min())
        cell = base * 2.0**current
        at_level = pending[level[pending] == current]
        # the grid cannot help (any more)
        if cell > diagonal or cell < diagonal * 2.0**-_FINEST_GRID_BITS:
            brute.append(at_level)
            pending = pending[level[pending] != current]
            continue
        sq, exact, crowded = _grid_knn(pts, at_level, k, cell, lo)
        done = exact & ~crowded
        result[at_level[done]] = sq[done]
        up, down = at_level[~exact & ~crowded], at_level[crowded]
        # A reversal, or a cluster that stays crowded at any cell size (many duplicates), goes to
        # brute force.
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
    """Starting cell size: the lower quartile of the k-th neighbour distance of a random sample of
    points."""
    n = points.shape[0]
    generator = torch.Generator().manual_seed(0)
    sample = torch.randperm(n, generator=generator, device="cpu")[: min(n, 64)].to(points.device)
    kth = _brute_force_knn(points, sample, k)[:, -1].sqrt()
    positive = kth[kth > 0]
    if positive.numel() == 0:
        return float("nan")
    return float(torch.quantile(positive, 0.25)) * 1.01


def _brute_force_knn(points: torch.Tensor, queries: torch.Tensor, k: int) -> torch.Tensor:
    """(Q, k) ascending squared distances from ``points[queries]`` to their k nearest other
    points."""
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


_NEIGHBOUR_OFFSETS = torch.tensor(
    [(i, j, l) for i in (-1, 0, 1) for j in (-1, 0, 1) for l in (-1, 0, 1)], device="cpu"
)
# A query whose 27 cells hold more candidates than this is sent to a finer grid, down to cells of
# diagonal / 2**_FINEST_GRID_BITS (cell keys must fit in int64; clusters of duplicates end in brute
# force).
_MAX_CANDIDATES = 2048
_FINEST_GRID_BITS = 20


def _grid_knn(
    points: torch.Tensor, queries: torch.Tensor, k: int, cell: float, lo: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """k-NN among the 27 grid cells around each query.

    Returns (Q, k) ascending squared distances, ``exact`` (Q,) (k-th distance ≤ cell, so nothing
    outside the block can be closer) and ``crowded`` (Q,) (more than ``_MAX_CANDIDATES`` candidates:
    not searched).
    """
    device = points.device
    cells = torch.floor((points - lo) / cell).long()
    dims = cells.max(0).values + 1
    keys = (cells[:, 0] * dims[1] + cells[:, 1]) * dims[2] + cells[:, 2]
    sorted_keys, order = torch.sort(keys)
    unique_keys, unique_counts = torch.unique_consecutive(sorted_keys, return_counts=True)
    unique_starts = torch.cumsum(unique_counts, 0) - unique_counts

    # The 27 neighbour cells of a query differ from its own key by constant offsets; only the bounds
    # vary.
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
        counts = torch.where(
            inside & (unique_keys[slot] == nkeys), unique_counts[slot], torch.zeros_like(slot)
        )
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
            within = (
                torch.arange(total, device=device) - (torch.cumsum(q_counts, 0) - q_counts)[seg]
            )
            candidate = order[start[first:last].reshape(-1)[seg] + within]
            local_query = torch.div(seg, offsets.shape[0], rounding_mode="floor")
            query = queries[first:last][local_query]
            diff = points[candidate] - points[query]
            sq = torch.einsum("pc,pc->p", diff, diff).masked_fill(candidate == query, float("inf"))
            row_counts = per_query[first:last]
            row_first = torch.cumsum(row_counts, 0) - row_counts
            dense = torch.full(
                (last - first, max(int(row_counts.max()), k)), float("inf"), device=device
            )
            dense[local_query, torch.arange(total, device=device) - row_first[local_query]] = sq
            sq_out[first:last] = torch.topk(dense, k, dim=1, largest=False).values
        first = last
    # Nothing outside the 27-cell block is closer than the distance from the query to the block's
    # boundary. in [0, 1) within its own cell
    position = (points[queries] - lo) / cell - qcells.to(points.dtype)
    margin = cell * (1.0 + torch.minimum(position, 1.0 - position).min(1).values.clamp(0.0, 1.0))
    exact = sq_out[:, -1] <= margin * margin
    return sq_out, exact, crowded
