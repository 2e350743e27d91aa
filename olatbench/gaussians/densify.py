"""3DGS adaptive density control (clone, split, prune, opacity reset) plus a priority cap on the
count.

Usage per training iteration (after ``loss.backward()``, before ``optimizer.step()``)::

    projected.means2d.retain_grad()          # before backward
    ...
    densifier.accumulate(projected.means2d.grad, projected.radii, projected.radii > 0,
                         width=projected.width, height=projected.height)
    densifier.accumulate_priority(shadow.weight)         # optional (SSD-GS light-view weight)
    stats = densifier.step(model, optimizer, iteration, scene_extent)  # the runner's step + 1

(`observe_and_step` does the last three from the runner's 0-based step.) Conventions follow the
reference 3DGS code (and SSD-GS, which uses it unchanged):

- the densification statistic is the mean, over the iterations in which a Gaussian was visible, of
  the norm of the view-space 2D-mean gradient **in NDC units**: the pixel gradient is multiplied by
  (W/2, H/2), which is what the 0.0002 threshold was tuned for (SSD-GS's gsplat port does the same
  rescaling);
- clone: gradient ≥ threshold and max scale ≤ ``percent_dense`` × extent -> an identical copy;
- split: gradient ≥ threshold and max scale > ``percent_dense`` × extent -> ``split_count`` children
  sampled from the parent Gaussian, scales divided by 0.8 × ``split_count``, the parent removed;
- prune: opacity < ``min_opacity``; after the first opacity reset also screen radius >
  ``max_screen_size`` px (largest radius seen since the last densification) or max scale >
  ``max_world_size`` × extent;
- opacity reset every ``opacity_reset_interval``: opacity = min(opacity, 0.01), Adam moments of the
  opacity zeroed;
- cap (SSD-GS ``maximum_gs``): if more than ``max_gaussians`` remain, the ones with the smallest
  accumulated priority are removed. Gaussians created in this step get the largest priority
  (as the official code) so a fresh clone is never capped immediately. Unlike the official code, the
  cap is applied *after* the other pruning, so exactly ``max_gaussians`` survive instead of possibly
  fewer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any

import torch

from olatbench.gaussians.host_sync import allowed_host_sync
from olatbench.gaussians.model import GaussianModel
from olatbench.gaussians.optim import append_rows, replace_values, select_rows
from olatbench.gaussians.projection import quat_to_rotmat


@dataclass(frozen=True)
class DensifyConfig:
    """Adaptive density control settings; defaults are the 3DGS ones (iteration counts at 30K
    scale)."""

    densify_from: int = 500
    densify_until: int = 15_000
    densify_interval: int = 100
    grad_threshold: float = 0.0002
    opacity_reset_interval: int = 3000
    reset_opacity_at_start: bool = False  # 3DGS also resets at densify_from with a white background
    percent_dense: float = 0.01
    min_opacity: float = 0.005
    max_screen_size: float | None = 20.0  # px; None disables screen-size pruning
    max_world_size: float = 0.1  # × scene extent
    split_count: int = 2
    split_scale_divisor: float = 0.8  # children scales = parent / (divisor × split_count)
    reset_opacity_value: float = 0.01
    max_gaussians: int | None = None  # SSD-GS maximum_gs cap (None: no cap)

    _ITERATION_FIELDS = (
        "densify_from",
        "densify_until",
        "densify_interval",
        "opacity_reset_interval",
    )

    def scaled(self, factor: float) -> DensifyConfig:
        """A copy with every iteration threshold multiplied by ``factor``
        (for longer/shorter schedules)."""
        return replace(
            self,
            **{
                name: max(1, round(getattr(self, name) * factor)) for name in self._ITERATION_FIELDS
            },
        )

    def __post_init__(self) -> None:
        for field in fields(self):
            value = getattr(self, field.name)
            if field.name in self._ITERATION_FIELDS and value <= 0:
                raise ValueError(f"DensifyConfig.{field.name} must be positive, got {value}")
        if self.split_count < 2:
            raise ValueError(f"DensifyConfig.split_count must be ≥ 2, got {self.split_count}")
        if not 0.0 < self.reset_opacity_value < 1.0:
            raise ValueError(
                "DensifyConfig.reset_opacity_value must be in (0, 1), got "
                f"{self.reset_opacity_value}"
            )


class Densifier:
    """Accumulates densification statistics and applies 3DGS density control to a
    :class:`GaussianModel`."""

    def __init__(self, config: DensifyConfig | None = None, seed: int = 0) -> None:
        self.config = config or DensifyConfig()
        self.generator = torch.Generator().manual_seed(seed)
        self.grad_sum: torch.Tensor | None = None  # (N,) sum of NDC gradient norms while visible
        self.visible_count: torch.Tensor | None = None  # (N,) iterations visible
        # (N,) largest screen radius (px) since the last densification
        self.max_radii: torch.Tensor | None = None
        self.priority: torch.Tensor | None = None  # (N,) accumulated priority for the cap

    # --------------------------------------------------------------------------------------------
    # stats
    def _ensure(self, n: int, device: torch.device) -> None:
        if self.grad_sum is None or self.grad_sum.shape[0] != n:
            if self.grad_sum is not None and self.grad_sum.shape[0] != n:
                raise ValueError(
                    f"densification statistics are for {self.grad_sum.shape[0]} Gaussians but got "
                    f"{n}: change the count only through Densifier.step (or call reset(n))"
                )
            self.reset(n, device)

    def reset(self, n: int, device: torch.device | str = "cpu") -> None:
        """Zero the statistics for ``n`` Gaussians."""
        self.grad_sum = torch.zeros(n, device=device)
        self.visible_count = torch.zeros(n, device=device)
        self.max_radii = torch.zeros(n, device=device)
        self.priority = torch.zeros(n, device=device)

    def state_dict(self) -> dict[str, torch.Tensor | None]:
        """Running statistics and the split sampler's RNG state (tensors only; for checkpoints)."""
        return {
            "grad_sum": self.grad_sum,
            "visible_count": self.visible_count,
            "max_radii": self.max_radii,
            "priority": self.priority,
            "generator": self.generator.get_state(),
        }

    def load_state_dict(self, state: dict[str, torch.Tensor | None]) -> None:
        """Restore what :meth:`state_dict` returned (the config is not part of it)."""
        for name in ("grad_sum", "visible_count", "max_radii", "priority"):
            value = state[name]
            setattr(self, name, None if value is None else value.clone())
        self.generator.set_state(state["generator"])

    def active(self, iteration: int) -> bool:
        """Whether statistics are still collected at ``iteration`` (before ``densify_until``)."""
        return iteration < self.config.densify_until

    @torch.no_grad()
    def accumulate(
        self,
        means2d_grad: torch.Tensor,
        radii: torch.Tensor,
        visible: torch.Tensor,
        *,
        width: int,
        height: int,
    ) -> None:
        """Add one view: 2D-mean gradient (N, 2) in px units, screen radii (N,) px, visibility (N,)
        bool.

        ``width``/``height`` of that view convert the gradient to NDC units (× W/2, × H/2) as 3DGS
        does.
        """
        n = means2d_grad.shape[0]
        self._ensure(n, means2d_grad.device)
        scale = torch.tensor([0.5 * width, 0.5 * height], dtype=means2d_grad.dtype, device="cpu")
        scale = scale.to(means2d_grad.device, non_blocking=True)  # queued on a GPU, not waited for
        norm = (means2d_grad * scale).norm(dim=-1)
        visible = visible.to(torch.bool)
        # Dense masked updates: boolean indexing costs a nonzero() and a gather/scatter per
        # statistic.
        self.grad_sum += torch.where(visible, norm.to(self.grad_sum.dtype), 0.0)
        self.visible_count += visible
        self.max_radii = torch.where(
            visible, torch.maximum(self.max_radii, radii.to(self.max_radii.dtype)), self.max_radii
        )

    @torch.no_grad()
    def accumulate_priority(self, values: torch.Tensor) -> None:
        """Add a per-Gaussian priority (N,) (e.g. the light-view blending weight); used by the count
        cap."""
        self._ensure(values.shape[0], values.device)
        self.priority += values.to(self.priority.dtype)

    # ------------------------------------------------------------------------------------------
    # control
    @torch.no_grad()
    @torch.no_grad()
    def observe_and_step(
        self,
        model: GaussianModel,
        optimizer: torch.optim.Optimizer | None,
        projected: Any,
        step: int,
        scene_extent: float,
        priority: torch.Tensor | None = None,
    ) -> dict[str, int | bool]:
        """After the runner's training ``step`` (counted from 0): accumulate the view's 2D-mean
        gradients (and an optional per-Gaussian ``priority`` such as the light-view weight), then
        run `step` at iteration ``step + 1`` — the schedule is the official code's, whose iterations
        count from 1, so nothing resets the opacities at the very first step (0 % interval == 0).
        ``projected`` is the step's `Projected` with ``means2d.retain_grad()`` called before
        backward."""
        iteration = step + 1
        grad = projected.means2d.grad
        if grad is not None and self.active(iteration):
            self.accumulate(
                grad,
                projected.radii,
                projected.radii > 0,
                width=projected.width,
                height=projected.height,
            )
            if priority is not None:
                self.accumulate_priority(priority)
        return self.step(model, optimizer, iteration, scene_extent)

    def step(
        self,
        model: GaussianModel,
        optimizer: torch.optim.Optimizer | None,
        iteration: int,
        scene_extent: float,
    ) -> dict[str, int | bool]:
        """Run density control if ``iteration`` is scheduled (3DGS schedule); returns what happened.

        Keys: ``densified`` (bool), ``cloned``, ``split``, ``pruned``, ``capped``, ``opacity_reset``
        (bool), ``num_gaussians``.
        """
        cfg = self.config
        report: dict[str, int | bool] = {
            "densified": False,
            "cloned": 0,
            "split": 0,
            "pruned": 0,
            "capped": 0,
            "opacity_reset": False,
        }
        if iteration < cfg.densify_until:
            self._ensure(model.num_gaussians, model.means.device)
            if iteration > cfg.densify_from and iteration % cfg.densify_interval == 0:
                size_limit = cfg.max_screen_size if iteration > cfg.opacity_reset_interval else None
                # the new count is a value the device computes
                with allowed_host_sync("density-control"):
                    report.update(
                        self.densify_and_prune(model, optimizer, scene_extent, size_limit)
                    )
                report["densified"] = True
            if iteration % cfg.opacity_reset_interval == 0 or (
                cfg.reset_opacity_at_start and iteration == cfg.densify_from
            ):
                with allowed_host_sync("density-control"):
                    self.reset_opacity(model, optimizer)
                report["opacity_reset"] = True
        report["num_gaussians"] = model.num_gaussians
        return report

    @torch.no_grad()
    def densify_and_prune(
        self,
        model: GaussianModel,
        optimizer: torch.optim.Optimizer | None,
        scene_extent: float,
        max_screen_size: float | None,
    ) -> dict[str, int]:
        """Clone, split, prune and cap now (regardless of the schedule); statistics are reset
        afterwards."""
        cfg = self.config
        self._ensure(model.num_gaussians, model.means.device)
        params = list(model.per_gaussian_parameters().values())
        grads = self.grad_sum / self.visible_count.clamp_min(1)
        n0 = model.num_gaussians
        large = model.scales.max(dim=1).values > cfg.percent_dense * scene_extent
        hot = grads >= cfg.grad_threshold

        # Clone: copies of small hot Gaussians (appended; clones are never split in the same step).
        clone = hot & ~large
        append_rows(params, optimizer, [p[clone] for p in params])
        # Split: children of large hot Gaussians (among the original n0), then the parents are
        # removed.
        split = torch.zeros(model.num_gaussians, dtype=torch.bool, device=model.means.device)
        split[:n0] = hot & large
        children = self._split_children(model, split)
        append_rows(params, optimizer, children)

        # Priority of every current row: old rows keep theirs, new rows get the maximum.
        n_new = model.num_gaussians - n0
        top = self.priority.max() if n0 > 0 else torch.zeros((), device=self.priority.device)
        priority = torch.cat([self.priority, top.expand(n_new)])
        max_radii = torch.cat([self.max_radii, torch.zeros(n_new, device=self.max_radii.device)])

        split = torch.cat(
            [
                split,
                torch.zeros(n_new - (split.shape[0] - n0), dtype=torch.bool, device=split.device),
            ]
        )
        prune = split | (model.opacities < cfg.min_opacity)
        if max_screen_size is not None:
            prune |= max_radii > max_screen_size
            prune |= model.scales.max(dim=1).values > cfg.max_world_size * scene_extent
        keep = ~prune
        capped = 0
        if cfg.max_gaussians is not None and int(keep.sum()) > cfg.max_gaussians:
            kept = torch.nonzero(keep).squeeze(1)
            order = torch.argsort(priority[kept], descending=True, stable=True)
            dropped = kept[order[cfg.max_gaussians :]]
            keep[dropped] = False
            capped = int(dropped.numel())
        select_rows(params, optimizer, keep)
        self.reset(model.num_gaussians, model.means.device)
        return {
            "cloned": int(clone.sum()),
            "split": int(split.sum()),
            "pruned": int(prune.sum()) - int(split.sum()),
            "capped": capped,
        }

    def _split_children(self, model: GaussianModel, split: torch.Tensor) -> list[torch.Tensor]:
        """Rows to append for the split Gaussians: ``split_count`` samples each, in parameter
        order."""
        cfg = self.config
        count = cfg.split_count
        params = model.per_gaussian_parameters()
        scales = model.scales[split].repeat(count, 1)
        noise = torch.randn(
            scales.shape, generator=self.generator, dtype=scales.dtype, device="cpu"
        ).to(scales.device)
        rotations = quat_to_rotmat(model.quats[split]).repeat(count, 1, 1)
        offsets = (rotations @ (noise * scales)[..., None]).squeeze(-1)
        rows = {
            name: value[split].repeat(count, *([1] * (value.ndim - 1)))
            for name, value in params.items()
        }
        rows["means"] = rows["means"] + offsets
        rows["log_scales"] = torch.log(scales / (cfg.split_scale_divisor * count))
        return list(rows.values())

    @torch.no_grad()
    def reset_opacity(self, model: GaussianModel, optimizer: torch.optim.Optimizer | None) -> None:
        """Clamp every opacity to at most ``reset_opacity_value`` and zero the opacity's optimizer
        moments."""
        value = self.config.reset_opacity_value
        limit = math.log(value / (1.0 - value))
        replace_values(model.opacity_logits, optimizer, model.opacity_logits.clamp_max(limit))


__all__ = ["Densifier", "DensifyConfig"]
