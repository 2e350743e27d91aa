"""SSD-GS light-view visibility pass (forward only): a coarse shadow hint per Gaussian.

The Gaussians are splatted from a pinhole camera at the point light, sorted by squared distance to
the light and composited with the 3DGS rules; each Gaussian g gets ``visibility`` (N,) in [0, 1]
(the transmittance in front of g averaged near its projected centre, the paper's v̂_g, Eq. 6;
``mode`` picks the average, ``depth_offset`` the self-shadow band), ``weight`` (N,)
(Σ T·α: the light g intercepts) and ``seen`` (N,) bool; unseen Gaussians get
0. `OFFICIAL_KERNEL` reproduces the official kernel's arithmetic. Backends: ``"torch"`` (every
   option, any
device), ``"cpu"`` (C++; ``"uniform"`` and ``"density"``), ``"auto"``. docs/gaussians-training.md
("The light-view visibility pass") gives the modes, the light camera, the offset and what differs
from the official code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import torch

from olatbench._native import Unavailable
from olatbench.datasets.cameras import look_at
from olatbench.gaussians.host_sync import allowed_host_sync
from olatbench.gaussians.projection import project
from olatbench.gaussians.tiles import TileBins, bin_gaussians, float_order_key

ShadowMode = Literal["uniform", "density", "footprint"]
MODES = ("uniform", "density", "footprint")
CPU_MODES = ("uniform", "density")  # the modes the C++ kernel implements
OFFICIAL_DEPTH_OFFSET = 0.015  # squared-distance units (the official kernel's `offset`)
# Options reproducing the official SSD-GS light kernel (both backends).
OFFICIAL_KERNEL = {"mode": "density", "depth_offset": OFFICIAL_DEPTH_OFFSET}
MAX_FOV_DEGREES = 120.0
# Compositing constants of the rasterizer (kept identical to gaussians/csrc/rasterize.cpp).
_ALPHA_MAX = 0.99
_ALPHA_MIN = 1.0 / 255.0
_T_MIN = 1e-4
# Number of (pair, pixel) entries the torch reference handles at once.
_ENTRY_BUDGET = 1 << 22


@dataclass
class ShadowResult:
    """Per-Gaussian light-view results: ``visibility`` (N,) in [0, 1], ``weight`` (N,) ≥ 0, ``seen``
    (N,) bool, and the ``backend`` that computed them."""

    visibility: torch.Tensor
    weight: torch.Tensor
    seen: torch.Tensor
    backend: str


def camera_matched_focal(
    camera_fx: float | torch.Tensor,
    camera_width: int,
    resolution: int,
    camera_position: torch.Tensor,
    light_position: torch.Tensor,
    target: torch.Tensor,
) -> float | torch.Tensor:
    """Light-camera focal length (px) at which the scene around ``target`` appears at the viewing
    camera's pixel scale: the official SSD-GS framing. The camera's ``camera_fx`` (px, for an image
    ``camera_width`` px wide) is rescaled to the light view's ``resolution`` px and multiplied by
    |light − target| / |camera − target|.

    The official code takes both distances from the world origin, which is the same for a scene
    centred there (as object-centric captures usually are); measured from ``target`` the framing
    follows the scene wherever it is. The field of view is capped at ``MAX_FOV_DEGREES`` like
    :func:`light_camera`'s fitted one. ``camera_position``, ``light_position``, ``target``: (3,)
    world points. On CPU tensors a float, checked (a camera at the target raises); on a GPU a 0-d
    float64 tensor on the device, computed there without a host sync and unchecked."""
    if target.device.type != "cpu":
        return _camera_matched_focal_on_device(
            camera_fx, camera_width, resolution, camera_position, light_position, target
        )
    camera_fx = float(camera_fx)
    to_camera = float(
        (camera_position.detach().double().cpu() - target.detach().double().cpu()).norm()
    )
    to_light = float(
        (light_position.detach().double().cpu() - target.detach().double().cpu()).norm()
    )
    if not (to_camera > 0 and math.isfinite(to_camera) and math.isfinite(to_light)):
        raise ValueError(
            "camera-matched light framing needs a camera away from the target; distance "
            f"{to_camera}"
        )
    focal = camera_fx * resolution / camera_width * to_light / to_camera
    widest = 0.5 * resolution / math.tan(math.radians(MAX_FOV_DEGREES) / 2)
    return max(focal, widest)


def _camera_matched_focal_on_device(
    camera_fx: float | torch.Tensor,
    camera_width: int,
    resolution: int,
    camera_position: torch.Tensor,
    light_position: torch.Tensor,
    target: torch.Tensor,
) -> torch.Tensor:
    """`camera_matched_focal` as a 0-d float64 tensor on ``target``'s device, computed there
    (no host sync)."""
    to_camera = (camera_position.detach().double() - target.detach().double()).norm()
    to_light = (light_position.detach().double() - target.detach().double()).norm()
    fx = (
        camera_fx.detach().double()
        if isinstance(camera_fx, torch.Tensor)
        else torch.full_like(to_light, camera_fx)
    )
    focal = fx * resolution / camera_width * to_light / to_camera
    return focal.clamp_min(0.5 * resolution / math.tan(math.radians(MAX_FOV_DEGREES) / 2))


def light_camera(
    light_position: torch.Tensor,
    target: torch.Tensor,
    scene_radius: float | torch.Tensor = 1.0,
    resolution: int = 256,
    up: tuple[float, float, float] = (0.0, 0.0, 1.0),
    margin: float = 1.05,
    focal_px: float | torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor, int, int]:
    """Square pinhole camera at the light looking at ``target``: ``(w2c (4, 4), K (3, 3), width,
    height)``.

    The half field of view is ``asin(scene_radius / distance) × margin`` (the sphere around
    ``target`` just fits), capped at ``MAX_FOV_DEGREES`` / 2 — also when the light is inside that
    sphere. ``focal_px`` overrides the fitted focal length (e.g. the official choice: the viewing
    camera's focal length × |light| / |camera|). Tensors are float32 on the light's device; K
    follows the +0.5 pixel-centre convention (principal point at the image centre). A light on the
    CPU is framed on the host (numpy, `olatbench.datasets.cameras.look_at`; a light at the target or
    a non-positive focal length raise); elsewhere by `_light_camera_on_device`, the same formulas in
    float64 on the device without a host sync (``scene_radius`` and ``focal_px`` may then be tensors
    there), unchecked.
    """
    if light_position.device.type != "cpu":
        return _light_camera_on_device(
            light_position, target, scene_radius, resolution, up, margin, focal_px
        )
    eye = light_position.detach().double().cpu().numpy()
    centre = target.detach().double().cpu().numpy()
    distance = float(np.linalg.norm(centre - eye))
    if not distance > 0:
        raise ValueError(
            f"light position {eye.tolist()} coincides with the target {centre.tolist()}"
        )
    max_half = math.radians(MAX_FOV_DEGREES) / 2
    half = math.asin(scene_radius / distance) * margin if scene_radius < distance else max_half
    half = min(half, max_half)
    focal = 0.5 * resolution / math.tan(half) if focal_px is None else float(focal_px)
    if not focal > 0:
        raise ValueError(f"light camera focal length must be positive, got {focal}")
    c2w = look_at(eye, centre, np.asarray(up, dtype=np.float64))
    w2c = torch.as_tensor(np.linalg.inv(c2w), dtype=torch.float32, device=light_position.device)
    K = torch.tensor(
        [[focal, 0.0, resolution / 2.0], [0.0, focal, resolution / 2.0], [0.0, 0.0, 1.0]],
        dtype=torch.float32,
        device=light_position.device,
    )
    return w2c, K, int(resolution), int(resolution)


def _light_camera_on_device(
    light_position: torch.Tensor,
    target: torch.Tensor,
    scene_radius: float | torch.Tensor,
    resolution: int,
    up: tuple[float, float, float],
    margin: float,
    focal_px: float | torch.Tensor | None,
) -> tuple[torch.Tensor, torch.Tensor, int, int]:
    """`light_camera` computed on the light's device in float64 (`look_at`'s axes; the up fallback
    by a ``torch.where``; ``w2c`` as the rigid inverse [Rᵀ, -Rᵀ eye] of the camera-to-world)."""
    eye, centre = light_position.detach().double(), target.detach().double()
    distance = (centre - eye).norm()
    max_half = math.radians(MAX_FOV_DEGREES) / 2

    # a number is filled in on the device: no copy
    def on_device(value: float | torch.Tensor) -> torch.Tensor:
        return (
            value.detach().double()
            if isinstance(value, torch.Tensor)
            else torch.full_like(distance, value)
        )

    if focal_px is None:
        radius = on_device(scene_radius)
        inside = radius < distance
        half = torch.where(
            inside, torch.asin(torch.where(inside, radius / distance, 0.0)) * margin, max_half
        )
        focal = (0.5 * resolution) / torch.tan(half.clamp_max(max_half))
    else:
        focal = on_device(focal_px)
    forward = (centre - eye) / distance

    # made on the device: no copy from the host
    def vector(values: tuple[float, float, float]) -> torch.Tensor:
        return torch.stack([torch.full_like(distance, v) for v in values])

    right = torch.linalg.cross(forward, vector(up))
    fallback = torch.linalg.cross(
        forward, vector((0.0, 1.0, 0.0) if abs(up[1]) < 0.9 else (1.0, 0.0, 0.0))
    )
    right = torch.where(right.norm() < 1e-8, fallback, right)
    right = right / right.norm()
    # columns: c2w axes
    rotation = torch.stack([right, torch.linalg.cross(forward, right), forward], dim=1)
    bottom = torch.eye(4, dtype=torch.float64, device=eye.device)[3:]
    w2c = torch.cat([torch.cat([rotation.T, (-rotation.T @ eye)[:, None]], dim=1), bottom])
    zero, one, centre_px = (
        torch.zeros_like(focal),
        torch.ones_like(focal),
        torch.full_like(focal, resolution / 2.0),
    )
    K = torch.stack([focal, zero, centre_px, zero, focal, centre_px, zero, zero, one]).reshape(3, 3)
    return w2c.float(), K.float(), int(resolution), int(resolution)


@torch.no_grad()
def shadow_gather(
    means: torch.Tensor,
    quats: torch.Tensor,
    scales: torch.Tensor,
    opacities: torch.Tensor,
    light_position: torch.Tensor,
    target: torch.Tensor,
    resolution: int = 256,
    backend: str = "auto",
    *,
    mode: ShadowMode = "uniform",
    depth_offset: float = 0.0,
    radius_px: float = 2.0,
    scene_radius: float | None = None,
    focal_px: float | None = None,
    near: float = 0.01,
) -> ShadowResult:
    """Light-view coarse visibility, blending weight and seen flag per Gaussian
    (see the module docstring).

    ``means`` (N, 3), ``quats`` (N, 4) wxyz, ``scales`` (N, 3) linear, ``opacities`` (N,) in [0, 1],
    ``light_position`` (3,), ``target`` (3,). ``scene_radius`` defaults to the largest distance from
    ``target`` to a Gaussian centre; ``focal_px`` overrides the fitted focal length
    (see :func:`light_camera`). Forward only (no autograd).
    """
    if mode not in MODES:
        raise ValueError(f"unknown shadow mode {mode!r}; choose one of {', '.join(MODES)}")
    if not depth_offset >= 0:
        raise ValueError(f"depth_offset must be ≥ 0, got {depth_offset}")
    n = means.shape[0]
    dtype = means.dtype if means.dtype in (torch.float32, torch.float64) else torch.float32
    light = light_position.to(device=means.device, dtype=dtype)
    target = target.to(device=means.device, dtype=dtype)
    # only frames the view when no focal length is given (on a GPU: on the device)
    if scene_radius is None:
        radius = (means - target).norm(dim=1).max() if n > 0 and focal_px is None else 1.0
        scene_radius = float(radius) if means.device.type == "cpu" else radius
    w2c, K, width, height = light_camera(light, target, scene_radius, resolution, focal_px=focal_px)
    chosen = _choose_backend(backend, means.device, dtype, mode)
    zeros = torch.zeros(n, device=means.device, dtype=dtype)
    if n == 0:
        return ShadowResult(
            zeros, zeros.clone(), torch.zeros(0, dtype=torch.bool, device=means.device), chosen
        )
    projected = project(
        means.to(dtype),
        quats.to(dtype),
        scales.to(dtype),
        w2c.to(dtype),
        K.to(dtype),
        width,
        height,
        near=near,
    )
    keys = ((means.to(dtype) - light) ** 2).sum(-1)
    bins = bin_gaussians(
        projected.means2d,
        projected.radii,
        keys,
        width,
        height,
        backend="cpu" if chosen == "cpu" else "torch",
    )
    opacities = opacities.to(dtype).reshape(n)
    if chosen == "cpu":
        from olatbench.gaussians.backends.cpu import shadow_gather_cpu

        sums = shadow_gather_cpu(
            projected.means2d,
            projected.conics,
            opacities,
            bins,
            radius_px=radius_px,
            sort_keys=keys,
            depth_offset=depth_offset,
            density=mode == "density",
        )
        vis_sum, norm, weight = sums.vis_sum, sums.norm, sums.weight
        vis_sum, norm, weight = (t.to(means.device) for t in (vis_sum, norm, weight))
    else:
        vis_sum, norm, weight = _gather_torch(
            projected.means2d,
            projected.conics,
            opacities,
            keys,
            bins,
            mode,
            radius_px,
            depth_offset,
        )
    seen = (norm > 0) & (projected.radii > 0)
    visibility = torch.where(seen, vis_sum / norm.clamp_min(torch.finfo(dtype).tiny), zeros).clamp(
        0.0, 1.0
    )
    return ShadowResult(visibility=visibility, weight=weight, seen=seen, backend=chosen)


def _choose_backend(backend: str, device: torch.device, dtype: torch.dtype, mode: str) -> str:
    from olatbench.gaussians.backends import resolve_kernel_backend

    def cpu_inputs() -> Unavailable | None:
        if mode in CPU_MODES:
            return None
        return Unavailable(
            f"the C++ light pass implements mode={' and '.join(map(repr, CPU_MODES))} only, "
            f"got mode={mode!r}"
        )

    return resolve_kernel_backend(backend, device, dtype, "light-pass", cpu_inputs)


def _gather_torch(
    means2d: torch.Tensor,
    conics: torch.Tensor,
    opacities: torch.Tensor,
    keys: torch.Tensor,
    bins: TileBins,
    mode: str,
    radius_px: float,
    depth_offset: float,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Torch reference of the light pass on the tile bins: (visibility sum, normaliser, weight),
    each (N,).

    Same per-pixel compositing as the C++ kernel: every pixel walks its tile's front-to-back list.
    Only the (pair, pixel) entries that can matter are generated — pixels inside the box where the
    Gaussian's α can reach 1/255, or inside the ``radius_px`` sampling disc; elsewhere it neither
    attenuates nor samples. Entries are sorted by (pixel, list position) so each pixel's list is
    contiguous; transmittance is a segmented cumulative sum of log(1 - α) in float64.
    """
    device, dtype = means2d.device, means2d.dtype
    n = means2d.shape[0]
    offsets, ids = bins.offsets.to(device), bins.gaussian_ids.to(device)
    # vis_sum, norm, weight
    sums = [torch.zeros(n, device=device, dtype=torch.float64) for _ in range(3)]
    num_pairs = ids.numel()
    if num_pairs == 0:
        return tuple(t.to(dtype) for t in sums)
    pair_tiles = torch.repeat_interleave(
        torch.arange(bins.num_tiles, device=device),
        offsets[1:] - offsets[:-1],
        output_size=num_pairs,
    )

    # List position before which a pair's Gaussian reads its transmittance: itself, or with
    # depth_offset > 0 the first Gaussian of its tile whose key is not below key - depth_offset
    # (sorted pair keys: tile << 32 | key).
    if depth_offset > 0:
        pair_keys = (pair_tiles << 32) | float_order_key(keys[ids])
        shifted = (keys[ids].double() - depth_offset).to(keys.dtype)
        front_end = torch.searchsorted(pair_keys, (pair_tiles << 32) | float_order_key(shifted))
    else:
        front_end = torch.arange(num_pairs, device=device)

    x0, x1, y0, y1 = _pair_boxes(means2d, conics, opacities, bins, ids, pair_tiles, radius_px)
    entries = (x1 - x0 + 1).clamp_min(0) * (y1 - y0 + 1).clamp_min(0)
    tile_entries = torch.zeros(bins.num_tiles, dtype=torch.int64, device=device).index_add_(
        0, pair_tiles, entries
    )
    # The chunking is planned on the host from one copy of the per-tile entry counts and list
    # offsets.
    with allowed_host_sync("light-pass-entries"):
        layout = torch.cat([torch.cumsum(tile_entries, 0), offsets]).cpu()
    cumulative, offsets_host = layout[: bins.num_tiles], layout[bins.num_tiles :]
    tile = 0
    # chunks of whole tiles (so every pixel's list is complete) within the budget
    while tile < bins.num_tiles:
        reached = int(cumulative[tile - 1]) if tile else 0
        last = int(
            torch.searchsorted(
                cumulative, torch.tensor(reached + _ENTRY_BUDGET, device="cpu"), right=True
            )
        )
        last = min(max(last, tile + 1), bins.num_tiles)
        p0, p1 = int(offsets_host[tile]), int(offsets_host[last])
        total = int(cumulative[last - 1]) - reached
        if p1 > p0 and total > 0:
            box = (x0[p0:p1], x1[p0:p1], y0[p0:p1], entries[p0:p1])
            _gather_chunk(
                means2d,
                conics,
                opacities,
                bins.width,
                ids,
                front_end,
                p0,
                p1,
                box,
                total,
                mode,
                radius_px,
                depth_offset > 0,
                sums,
            )
        tile = last
    return tuple(t.to(dtype) for t in sums)


def _pair_boxes(means2d, conics, opacities, bins: TileBins, ids, pair_tiles, radius_px):
    """Inclusive pixel boxes (x0, x1, y0, y1) per (tile, Gaussian) pair: the tile ∩ image ∩ the box
    outside which the Gaussian surely has α < 1/255, widened to the sampling disc.
    Non-positive-definite conics get the tile."""
    slack = 0.05
    m = means2d[ids].double()
    a, b, c = conics[ids].double().unbind(-1)
    o = opacities[ids].double()
    det = a * c - b * b
    cut = -torch.log((255.0 * o).clamp_min(1e-30)) - 1e-3  # power below which o·exp(power) < 1/255
    proper = (det > 0) & (a > 0) & (c > 0)
    safe_det = torch.where(proper, det, torch.ones_like(det))
    hx = torch.sqrt((-2.0 * cut * c / safe_det).clamp_min(0.0)) + slack
    hy = torch.sqrt((-2.0 * cut * a / safe_det).clamp_min(0.0)) + slack
    hx = torch.where(o >= _ALPHA_MIN, hx, torch.full_like(hx, -1.0))
    hy = torch.where(o >= _ALPHA_MIN, hy, torch.full_like(hy, -1.0))
    hx = torch.where(proper, hx, torch.full_like(hx, 1e9)).clamp_min(radius_px + slack)
    hy = torch.where(proper, hy, torch.full_like(hy, 1e9)).clamp_min(radius_px + slack)
    ts = bins.tile_size
    tx0 = (pair_tiles % bins.tiles_x) * ts
    ty0 = torch.div(pair_tiles, bins.tiles_x, rounding_mode="floor") * ts
    tx1 = torch.clamp(tx0 + ts - 1, max=bins.width - 1)
    ty1 = torch.clamp(ty0 + ts - 1, max=bins.height - 1)
    x0 = torch.maximum(torch.ceil(m[:, 0] - 0.5 - hx).clamp(-1, 1e9).long(), tx0)
    x1 = torch.minimum(torch.floor(m[:, 0] - 0.5 + hx).clamp(-1, 1e9).long(), tx1)
    y0 = torch.maximum(torch.ceil(m[:, 1] - 0.5 - hy).clamp(-1, 1e9).long(), ty0)
    y1 = torch.minimum(torch.floor(m[:, 1] - 0.5 + hy).clamp(-1, 1e9).long(), ty1)
    return x0, x1, y0, y1


def _gather_chunk(
    means2d,
    conics,
    opacities,
    width,
    ids,
    front_end,
    p0,
    p1,
    box,
    total,
    mode,
    radius_px,
    offset,
    sums,
) -> None:
    """Accumulate the pairs [p0, p1) (whole tiles), ``total`` (pair, pixel) entries, into ``sums`` =
    [vis_sum, norm, weight] in place; ``offset``: whether a depth offset moved ``front_end`` off the
    pairs themselves."""
    device = means2d.device
    x0, x1, y0, counts = box
    pair = torch.repeat_interleave(torch.arange(p0, p1, device=device), counts, output_size=total)
    local = torch.arange(total, device=device) - (torch.cumsum(counts, 0) - counts)[pair - p0]
    box_width = (x1 - x0 + 1)[pair - p0]
    row = torch.div(local, box_width, rounding_mode="floor")
    px = x0[pair - p0] + local - row * box_width
    py = y0[pair - p0] + row
    pixel = py * width + px
    # Pixel-major order; within a pixel, list (pair) order.
    order = torch.sort(pixel * (p1 - p0) + (pair - p0)).indices
    pair, pixel, px, py = pair[order], pixel[order], px[order], py[order]
    g = ids[pair]

    dx = means2d[g, 0] - (px.to(means2d.dtype) + 0.5)
    dy = means2d[g, 1] - (py.to(means2d.dtype) + 0.5)
    a, b, c = conics[g].unbind(-1)
    power = -0.5 * (a * dx * dx + c * dy * dy) - b * dx * dy
    alpha = torch.clamp(opacities[g] * torch.exp(power), max=_ALPHA_MAX)
    candidate = (power <= 0) & (alpha >= _ALPHA_MIN)
    log_keep = torch.where(
        candidate, torch.log1p(-alpha.double()), torch.zeros_like(alpha, dtype=torch.float64)
    )

    # Exclusive prefix sums per pixel segment.
    prefix = torch.zeros(total + 1, device=device, dtype=torch.float64)
    prefix[1:] = torch.cumsum(log_keep, 0)
    new_pixel = torch.ones(total, dtype=torch.bool, device=device)
    new_pixel[1:] = pixel[1:] != pixel[:-1]
    seg_start = torch.cummax(
        torch.where(new_pixel, torch.arange(total, device=device), 0), 0
    ).values
    base = prefix[seg_start]
    cum_excl = prefix[:-1] - base
    cum_incl = prefix[1:] - base
    log_t_min = math.log(_T_MIN)
    composited = candidate & (cum_incl >= log_t_min)
    weight = torch.where(
        composited, alpha.double() * torch.exp(cum_excl), torch.zeros_like(cum_excl)
    )

    if not offset:  # read T just before the entry itself
        front = cum_excl
    else:  # first entry of the pixel whose list position is ≥ front_end (entries are sorted by it)
        sorted_key = pixel * (p1 - p0) + (pair - p0)
        position = torch.searchsorted(sorted_key, pixel * (p1 - p0) + (front_end[pair] - p0))
        front = prefix[position] - base
    t_front = torch.where(front >= log_t_min, torch.exp(front), torch.zeros_like(front))
    if mode == "footprint":
        sample, rho = candidate, torch.exp(power.double())
    else:
        sample = dx * dx + dy * dy <= radius_px * radius_px
        rho = torch.exp(power.double()) if mode == "density" else torch.ones_like(t_front)
    rho = torch.where(sample, rho, torch.zeros_like(rho))
    sums[0].index_add_(0, g, rho * t_front)
    sums[1].index_add_(0, g, rho)
    sums[2].index_add_(0, g, weight)


__all__ = [
    "MODES",
    "OFFICIAL_DEPTH_OFFSET",
    "OFFICIAL_KERNEL",
    "ShadowResult",
    "camera_matched_focal",
    "light_camera",
    "shadow_gather",
]
