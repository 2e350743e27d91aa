"""Training plumbing shared by the Gaussian methods (SSD-GS and the in-process baselines).

`TrainingViews` holds the training cameras and lights as tensors and draws views as 3DGS does (a
fresh random permutation per epoch); `VisibleSubset` / `shaded_subset` pick the Gaussians a view
shades (those in the frustum, or with contribution culling those that reach a pixel);
`photometric_loss` is the 3DGS loss ``(1 - λ) L1 + λ (1 - SSIM)``; `initial_model`,
`per_gaussian_groups` and `make_densifier` build the model, its optimiser groups and its density
control from the config fields every method shares (``num_init_gaussians``, ``init_radius``,
``init_opacity``, the ``densify_*`` windows given at ``reference_iterations`` and scaled by the
config's ``steps``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from olatbench.gaussians.contribution import max_weights
from olatbench.gaussians.densify import Densifier, DensifyConfig
from olatbench.gaussians.model import GaussianModel
from olatbench.gaussians.projection import Projected
from olatbench.gaussians.tiles import TileBins
from olatbench.methods.base import Views
from olatbench.methods.initialisation import initial_ball
from olatbench.metrics.decibels import psnr_from_mse
from olatbench.metrics.ssim import ssim_loss

if TYPE_CHECKING:
    from olatbench.datasets.records import Camera, PointLight


class VisibleSubset:
    """The Gaussians one view shades: projected radius > 0 (and ``keep``, when given), for
    per-Gaussian work on those only (on the CPU; on a GPU every Gaussian is shaded and the others'
    rows zeroed by a ``torch.where``, so that the subset's size never has to be read on the host).

    ``pick`` selects their rows of an (N, ...) tensor and ``scatter`` puts (K, C) values back into
    (N, C) rows (zeros for the others). When the subset is every Gaussian (common for an object in
    frame) both are the identity: no gather, no scatter, no copies in the autograd graph.
    """

    def __init__(self, radii: torch.Tensor, keep: torch.Tensor | None = None) -> None:
        self.total = int(radii.shape[0])
        self.mask = radii > 0 if keep is None else (radii > 0) & keep
        # on a GPU every row, masked: the subset's size is a host sync
        if radii.device.type != "cpu":
            self.indices, self.everything = None, False
            return
        self.indices = torch.nonzero(self.mask).squeeze(1)
        self.everything = int(self.indices.numel()) == self.total

    def pick(self, values: torch.Tensor) -> torch.Tensor:
        """(N, ...) -> (K, ...) rows of the subset (on a GPU K = N: every row)."""
        return values if self.everything or self.indices is None else values[self.indices]

    def scatter(self, values: torch.Tensor) -> torch.Tensor:
        """(K, C) -> (N, C), zero rows for the Gaussians outside the subset."""
        if self.everything:
            return values
        if self.indices is None:
            return torch.where(self.mask[:, None], values, torch.zeros_like(values))
        return values.new_zeros(self.total, values.shape[1]).index_copy(0, self.indices, values)


def shaded_subset(
    projected: Projected,
    opacities: torch.Tensor,
    cull_epsilon: float | None,
) -> tuple[VisibleSubset, TileBins | None]:
    """The Gaussians a view shades and, when culling ran, its tile binning (to pass to `rasterize`).

    ``cull_epsilon`` None: every visible Gaussian (radius > 0). Otherwise contribution culling
    (`olatbench.gaussians.contribution`): only those whose largest blending weight in the view
    exceeds it."""
    if cull_epsilon is None:
        return VisibleSubset(projected.radii), None
    contribution = max_weights(projected, opacities)
    return VisibleSubset(projected.radii, contribution.max_weight > cull_epsilon), contribution.bins


class TrainingViews:
    """The training views on ``device``: ``Ks`` (N,3,3), ``w2cs`` (N,4,4), ``light_positions``
    (N,3), ``light_intensities`` (N,3) and the images (N,H,W,3) in [0,1], plus the epoch-wise view
    order."""

    def __init__(self, views: Views, device: torch.device, seed: int) -> None:
        if len(views) == 0:
            raise ValueError("no training views")
        f32 = dict(dtype=torch.float32, device=device)
        self.views = views
        self.device = device
        self.Ks = torch.as_tensor(np.stack([c.K for c in views.cameras]), **f32)
        self.w2cs = torch.as_tensor(np.stack([c.w2c() for c in views.cameras]), **f32)
        self.light_positions = torch.as_tensor(
            np.stack([lt.position for lt in views.lights]), **f32
        )
        self.light_intensities = torch.as_tensor(
            np.stack([lt.intensity for lt in views.lights]), **f32
        )
        self.background = torch.as_tensor(
            np.asarray(views.background, dtype=np.float32).reshape(3), **f32
        )
        centres = np.stack([c.position for c in views.cameras])
        # 3DGS's cameras_extent: 1.1 × the largest camera distance from the mean camera centre.
        self.scene_extent = float(1.1 * np.linalg.norm(centres - centres.mean(0), axis=1).max())
        self.generator = torch.Generator().manual_seed(seed)
        self.order = torch.randperm(len(views), generator=self.generator, device="cpu")
        self.cursor = 0

    def __len__(self) -> int:
        return len(self.views)

    def next_index(self) -> int:
        """The next training view (every view once per epoch, in a fresh random order)."""
        if self.cursor >= len(self.order):
            self.order = torch.randperm(len(self.views), generator=self.generator, device="cpu")
            self.cursor = 0
        index = int(self.order[self.cursor])
        self.cursor += 1
        return index

    def image(self, index: int) -> torch.Tensor:
        """Training image ``index`` (H, W, 3) on the device."""
        image = torch.from_numpy(np.ascontiguousarray(self.views.images[index]))
        # queued, not waited for, on a GPU
        return image.to(self.device, torch.float32, non_blocking=True)

    def state_dict(self) -> dict[str, Any]:
        return {
            "generator": self.generator.get_state(),
            "order": self.order.clone(),
            "cursor": self.cursor,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.generator.set_state(state["generator"])
        self.order = state["order"].clone()
        self.cursor = int(state["cursor"])


def host_to_device(values: np.ndarray, device: torch.device) -> torch.Tensor:
    """``values`` as a float32 tensor on ``device``, uploaded without waiting for the device
    (``non_blocking``: a GPU queues the copy; the host does not synchronise)."""
    return torch.as_tensor(values, dtype=torch.float32, device="cpu").to(device, non_blocking=True)


def camera_tensors(camera: Camera, device: torch.device) -> tuple[torch.Tensor, torch.Tensor]:
    """``(w2c (4,4), K (3,3))`` of one camera as float32 tensors on ``device``."""
    return host_to_device(camera.w2c(), device), host_to_device(camera.K, device)


def light_tensors(light: PointLight, device: torch.device) -> tuple[torch.Tensor, torch.Tensor]:
    """``(position (3,), intensity (3,))`` of one point light as float32 tensors on ``device``."""
    return host_to_device(light.position, device), host_to_device(light.intensity, device)


def shaded_intensity(intensity: torch.Tensor, ignored: bool) -> torch.Tensor:
    """The light intensity (3,) the shading multiplies by: the recorded one, or 1 where the method's
    ``light_intensity`` setting ignores it (exactly what a light without a recorded intensity reads
    as)."""
    return torch.ones_like(intensity) if ignored else intensity


def camera_centre(w2c: torch.Tensor) -> torch.Tensor:
    """World-space camera centre (3,) of a world-to-camera matrix (4,4): ``-Rᵀ t``."""
    return -w2c[:3, :3].T @ w2c[:3, 3]


def photometric_loss(
    image: torch.Tensor, target: torch.Tensor, lambda_dssim: float
) -> tuple[torch.Tensor, torch.Tensor]:
    """``((1 - λ) L1 + λ (1 - SSIM), L1)`` of (H, W, 3) images (SSIM: the 3DGS zero-padded
    variant)."""
    l1 = (image - target).abs().mean()
    return (1.0 - lambda_dssim) * l1 + lambda_dssim * ssim_loss(
        image, target, channels_last=True
    ), l1


def psnr_of(image: torch.Tensor, target: torch.Tensor) -> float:
    """PSNR (dB, peak 1) of two images, for training logs."""
    return float(step_psnr(image, target))


class LazyScalar:
    """A scalar of `Method.train_step` computed from values on the device and read on the host only
    when ``float()`` asks (the runner, at its logging interval): ``read`` () -> float does the
    reading."""

    def __init__(self, read: Callable[[], float]) -> None:
        self.read = read

    def __float__(self) -> float:
        return float(self.read())


def step_psnr(image: torch.Tensor, target: torch.Tensor) -> LazyScalar:
    """`psnr_of` as a `LazyScalar`: the squared error is averaged on the device now, read when
    asked."""
    mse = ((image.detach() - target) ** 2).mean()
    return LazyScalar(lambda: psnr_from_mse(float(mse)))


def initial_count(views: Views, config: Any) -> int:
    """How many Gaussians `initial_model` makes: one per point of ``views.points``, else
    ``config.num_init_gaussians``."""
    return len(views.points) if views.points is not None else config.num_init_gaussians


def initial_model(
    views: Views, config: Any, attributes: dict[str, torch.Tensor], seed: int, device: torch.device
) -> GaussianModel:
    """``config.num_init_gaussians`` Gaussians with opacity ``config.init_opacity`` and the given
    per-Gaussian ``attributes`` (each (num_init_gaussians, ...)), uniform in `initial_ball`
    (``config.init_radius``) or, with ``config.init_shape == "box"``, in the cube of half-side
    radius / 2 around its centre (radius 1: the official SSD-GS code's [-0.5, 0.5]³; a fitted radius
    scales the cube with the scene). With ``views.points``: one Gaussian on each point instead
    (``attributes`` then have one row per point; `initial_count`), scaled as 3DGS does by the
    distance to its nearest neighbours (`GaussianModel.from_points`)."""
    if views.points is not None:
        return GaussianModel.from_points(
            views.points, attributes=attributes, opacity=config.init_opacity, device=device
        )
    centre, radius = initial_ball(views.cameras, config.init_radius)
    if config.init_shape == "box":
        return GaussianModel.random_in_box(
            config.num_init_gaussians,
            tuple((centre - radius / 2).tolist()),
            tuple((centre + radius / 2).tolist()),
            attributes=attributes,
            seed=seed,
            device=device,
            opacity=config.init_opacity,
        )
    return GaussianModel.random_in_sphere(
        config.num_init_gaussians,
        radius,
        attributes=attributes,
        seed=seed,
        device=device,
        center=tuple(centre.tolist()),
        opacity=config.init_opacity,
    )


def per_gaussian_groups(model: GaussianModel) -> list[dict[str, Any]]:
    """One optimiser group per per-Gaussian parameter, named as
    `GaussianModel.per_gaussian_parameters` (rates are set every step); the `Densifier` finds the
    groups it must resize by these names."""
    return [
        {"params": [p], "name": name, "lr": 0.0}
        for name, p in model.per_gaussian_parameters().items()
    ]


def make_densifier(config: Any, background: np.ndarray, seed: int) -> Densifier:
    """3DGS density control from the config's windows (scaled to the run with their floors:
    `GaussianConfig.density_windows`); opacities are also reset at the start on white backgrounds,
    as the official scripts do."""
    windows = config.density_windows()
    return Densifier(
        DensifyConfig(
            densify_from=windows.densify_from,
            densify_until=windows.densify_until,
            densify_interval=windows.interval,
            grad_threshold=config.densify_grad_threshold,
            opacity_reset_interval=windows.opacity_reset_interval,
            percent_dense=config.percent_dense,
            reset_opacity_at_start=bool(np.allclose(background, 1.0)),
            max_gaussians=config.max_gaussians,
        ),
        seed=seed,
    )
