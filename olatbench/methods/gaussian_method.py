"""The shared base of the Gaussian methods (SSD-GS, GS³, 3DGS): written once, specialised by hooks.

A `GaussianMethod` owns what the three share: the set-up order (checks, ``torch.manual_seed(seed)``,
the training views, the initial model, the method's own modules, the optimisers, the densifier), two
Adam optimisers — one group per per-Gaussian parameter (resized by densification) and the method's
global groups, declared as data by `global_groups` — whose rates come every step from the method's
learning-rate table `learning_rates`, the training step (frozen parameters, forward, the 3DGS
photometric loss, backward, then update and densification in the order `densify_before_update`
says), and the checkpoint (its format string and config checked on load). A method supplies its
initial per-Gaussian attributes, its modules, its global groups, its rate table, its forward pass
and its rendering. Everything a method does happens in the canonical frame of the training views
(`Views.frame`): `setup` moves the training views into it and `render` moves the world cameras and
lights it is given (docs/architecture.md, "The canonical frame").

The order of every call that consumes random numbers is fixed here, so methods moved onto this base
train to the same numbers as before.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import torch

from olatbench.datasets.similarity import Similarity
from olatbench.gaussians.optim import make_adam
from olatbench.methods.backends import stage_backends
from olatbench.methods.base import Method, Views
from olatbench.methods.shading.precision import check_precision, loss_scaler_for
from olatbench.methods.training import (
    TrainingViews,
    initial_count,
    initial_model,
    make_densifier,
    per_gaussian_groups,
    photometric_loss,
    step_psnr,
)

if TYPE_CHECKING:
    from olatbench.datasets.records import Camera, PointLight


@dataclass
class ParameterGroup:
    """One global optimiser group: ``name`` keys the method's learning-rate table (several groups
    may share a name and so a rate); ``lr`` is the rate at construction
    (every step sets the table's)."""

    name: str
    params: list[torch.nn.Parameter] = field(default_factory=list)
    lr: float = 0.0


VIEWER_SH_REST = 15  # SH coefficients above degree 0 at degree 3, the degree 3DGS files have


@dataclass(frozen=True)
class SplatColour:
    """How a method's Gaussians look in a splat viewer (`olatbench.gaussians.splat_ply`): 3DGS
    spherical-harmonic coefficients ``sh_dc`` (N, 3) and ``sh_rest`` (N, R, 3), R ≥ 0 (colour ``0.5
    + C0 · sh_dc`` + view-dependent terms), the attribute names they encode (``encoded``: not
    repeated as extra properties) and a one-line ASCII ``description`` for the file's header."""

    sh_dc: torch.Tensor
    sh_rest: torch.Tensor
    encoded: tuple[str, ...]
    description: str


def albedo_splat_colour(raw_diffuse: torch.Tensor, colourspace: str) -> SplatColour:
    """The colour of a method whose diffuse term is ``softplus(raw_diffuse) / π · cos θ · L / d²``
    (SSD-GS, GS³): the albedo ``softplus(raw_diffuse)`` (N, 3), converted from the job's
    ``colourspace`` to sRGB and clipped to [0, 1] (what a viewer shows), as the degree-0 SH
    coefficient; the 15 higher coefficients of degree 3 are zero (the original 3DGS loader asserts
    degree 3's count)."""
    from olatbench.datasets.colour import convert_colourspace
    from olatbench.methods.baselines.sh import rgb_to_sh_dc

    albedo = torch.nn.functional.softplus(raw_diffuse.detach().float().cpu()).numpy()
    shown = np.clip(convert_colourspace(albedo, colourspace, "srgb"), 0.0, 1.0)
    # no view dependence, in the degree-3 layout loaders expect (on the CPU, like the albedo: a file
    # is written)
    rest = torch.zeros(len(shown), VIEWER_SH_REST, 3, device="cpu")
    return SplatColour(
        rgb_to_sh_dc(torch.from_numpy(shown)),
        rest,
        ("diffuse",),
        f"colour: diffuse albedo softplus(diffuse), {colourspace} -> sRGB, clipped to [0, 1]",
    )


class GaussianMethod(Method):
    """A method on the shared Gaussian core. Subclasses set ``state_format`` and ``label`` and
    implement the abstract hooks; their config has the shared fields (``num_init_gaussians``,
    ``init_radius``, ``init_opacity``, ``lambda_dssim``, the ``densify_*`` windows,
    ``percent_dense``, ``max_gaussians``, ``steps()``, ``to_dict()``)."""

    state_format: ClassVar[str]  # checkpoint format, e.g. "olatbench.methods.ssdgs/2"
    label: ClassVar[str]  # the method's name in messages, e.g. "SSD-GS"
    #: `setup` reads cameras, lights and the background only; the images are read per training step.
    restore_needs_images: ClassVar[bool] = False

    def __init__(self, config: Any | None = None) -> None:
        super().__init__(config if config is not None else self.config_class())
        self.step = 0  # steps taken so far (the next train_step is normally called with this value)

    @classmethod
    def splat_colour(cls, attributes: Mapping[str, torch.Tensor], colourspace: str) -> SplatColour:
        """The viewer colour of trained Gaussians from their raw per-Gaussian ``attributes``
        (name -> (N, ...)) and the job's ``colourspace``, for ``olatbench export``. A method on this
        base says how (default: it cannot)."""
        raise NotImplementedError(
            f"{cls.label} does not say how its Gaussians are coloured in a splat viewer "
            "(GaussianMethod.splat_colour)"
        )

    def colours_under(self, camera: Camera, light: PointLight) -> torch.Tensor:
        """The colour (N, 3) each trained Gaussian contributes to a render from ``camera`` under
        ``light`` (both in the method's canonical frame, `canonical_view`), in the job's colour
        space, for every Gaussian (none culled); for `olatbench export --under-light`. A relightable
        method on this base says how (default: it cannot)."""
        raise NotImplementedError(
            f"{self.label} does not say what colour its Gaussians have under a light "
            "(GaussianMethod.colours_under)"
        )

    # -------------------------------------------------------------------------------------------
    # set-up
    def setup(self, train: Views, device: str | torch.device, seed: int) -> None:
        if len(train) == 0:
            raise ValueError(f"{self.label}: no training views")
        self.device = torch.device(device)
        check_precision(self.network_precision, self.device, self.label)
        self.loss_scaler = loss_scaler_for(self.network_precision)
        # world -> canonical; the method sees only canonical cameras and lights
        self.frame = train.frame
        train = train.in_frame()
        self.prepare(train)
        torch.manual_seed(seed)
        # tensors, scene extent, epoch-wise view order
        self.train_views = TrainingViews(train, self.device, seed)
        self.model = initial_model(
            train,
            self.config,
            self.initial_attributes(initial_count(train, self.config)),
            seed,
            self.device,
        )
        self.build_modules(train)
        self._build_optimisers()
        self.densifier = make_densifier(
            self.config, np.asarray(train.background, dtype=np.float32).reshape(3), seed
        )
        self.step = 0

    def prepare(self, train: Views) -> None:
        """Checks and derived settings before anything random happens (default: none)."""

    @property
    def network_precision(self) -> str:
        """The per-Gaussian networks' precision (``network_precision`` of the config; "fp32" without
        one)."""
        return getattr(self.config, "network_precision", "fp32")

    @abstractmethod
    def initial_attributes(self, n: int) -> dict[str, torch.Tensor]:
        """The per-Gaussian attributes of the ``n`` initial Gaussians
        (on the CPU; no random numbers)."""

    def build_modules(self, train: Views) -> None:
        """The method's modules after the model (shader, refinements), in a fixed order
        (default: none)."""

    def global_groups(self) -> list[ParameterGroup]:
        """The global optimiser's parameter groups, in order (default: none, so no global
        optimiser)."""
        return []

    def _build_optimisers(self) -> None:
        self.gaussian_optimizer = make_adam(per_gaussian_groups(self.model))
        groups = self.global_groups()
        self.global_optimizer = (
            make_adam([{"params": g.params, "name": g.name, "lr": g.lr} for g in groups])
            if groups
            else None
        )

    @property
    def optimizers(self) -> list[torch.optim.Optimizer]:
        """The per-Gaussian optimiser, then the global one when the method has global groups."""
        return [self.gaussian_optimizer] + (
            [self.global_optimizer] if self.global_optimizer is not None else []
        )

    # -------------------------------------------------------------------------------------------
    # frame
    def canonical_view(self, camera: Camera, light: PointLight) -> tuple[Camera, PointLight]:
        """A world camera and light (as the runner, reports and viewer give them) in the method's
        canonical frame."""
        return self.frame.camera(camera), self.frame.light(light)

    def world_view(self, camera: Camera, light: PointLight) -> tuple[Camera, PointLight]:
        """A canonical camera and light back in the dataset's world frame."""
        inverse = self.frame.inverse()
        return inverse.camera(camera), inverse.light(light)

    def render(self, camera: Camera, light: PointLight) -> dict[str, torch.Tensor]:
        """`render_canonical` of the view moved into the canonical frame (`Views.frame`)."""
        return self.render_canonical(*self.canonical_view(camera, light))

    @abstractmethod
    def render_canonical(self, camera: Camera, light: PointLight) -> dict[str, torch.Tensor]:
        """`Method.render` of a camera and light in the canonical frame."""

    # ----------------------------------------------------------------------------------------
    # training
    @abstractmethod
    def learning_rates(self, step: int) -> dict[str, float]:
        """The rate of every parameter-group name at ``step`` (per-Gaussian names as
        `GaussianModel.per_gaussian_parameters`, global names as `global_groups`)."""

    def frozen_parameters(self, step: int) -> list[torch.nn.Parameter]:
        """Parameters held fixed at ``step`` (their gradients are dropped before the update;
        default: none)."""
        return []

    @abstractmethod
    def training_forward(self, index: int, step: int) -> dict[str, Any]:
        """Forward pass of training view ``index`` at ``step``: ``image`` (H, W, 3), ``projected``
        (the projection, for densification) and ``light_weight`` (per-Gaussian densification
        priority or None)."""

    def clamp_render(self, render: torch.Tensor) -> torch.Tensor:
        """The render the loss sees (default: clamped to [0, 1])."""
        return render.clamp(0.0, 1.0)

    def loss(
        self, render: torch.Tensor, target: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(image, ``(1-λ)·L1 + λ·(1-SSIM)``, L1) of a render (H, W, 3) against its target."""
        image = self.clamp_render(render)
        return (image, *photometric_loss(image, target, self.config.lambda_dssim))

    def compute_gradients(self, step: int, index: int | None = None) -> dict[str, Any]:
        """Forward + backward of one training view (no parameter update); frozen parameters keep
        ``grad = None``.

        Returns the scalars of `train_step` plus ``projected`` and ``light_weight``
        (densification statistics)."""
        views = self.train_views
        index = views.next_index() if index is None else index
        frozen = self.frozen_parameters(step)
        for p in frozen:
            p.requires_grad_(False)
        try:
            out = self.training_forward(index, step)
            target = views.image(index)
            image, loss, l1 = self.loss(out["image"], target)
            out["projected"].means2d.retain_grad()
            (loss if self.loss_scaler is None else self.loss_scaler.scaled(loss)).backward()
        finally:
            for p in frozen:
                p.requires_grad_(True)
                p.grad = None
        return {
            "loss": loss.detach(),
            "l1": l1.detach(),
            "psnr": step_psnr(image, target),
            "projected": out["projected"],
            "light_weight": out["light_weight"],
        }

    @property
    def densify_before_update(self) -> bool:
        """Whether density control runs before the Adam update (the official codes' order: its
        surgery drops the gradients of the parameters it resizes, so they skip that update) instead
        of after it (default)."""
        return False

    def after_density_control(self, step: int, report: dict[str, int | bool]) -> None:
        """Called after each step's density control with the `Densifier.step` report
        (default: nothing)."""

    def step_summary(self, step: int) -> dict[str, float]:
        """Extra scalars of `train_step` (default: none)."""
        return {}

    def train_step(self, step: int) -> dict[str, Any]:
        rates = self.learning_rates(step)
        for optimizer in self.optimizers:
            for group in optimizer.param_groups:
                group["lr"] = rates[group["name"]]
        result = self.compute_gradients(step)
        projected, light_weight = result.pop("projected"), result.pop("light_weight")
        if self.loss_scaler is not None and not self._unscale_gradients(projected.means2d.grad):
            # an overflow: skip the whole update (as GradScaler skips .step)
            for optimizer in self.optimizers:
                optimizer.zero_grad(set_to_none=True)
            self.step = step + 1
            result.update(num_gaussians=float(self.model.num_gaussians), skipped=1.0)
            return result

        def density_control() -> dict[str, int | bool]:
            return self.densifier.observe_and_step(
                self.model,
                self.gaussian_optimizer,
                projected,
                step,
                self.train_views.scene_extent,
                priority=light_weight,
            )

        report = density_control() if self.densify_before_update else None
        for optimizer in self.optimizers:
            optimizer.step()
        for optimizer in self.optimizers:
            optimizer.zero_grad(set_to_none=True)
        if report is None:
            report = density_control()
        self.after_density_control(step, report)
        self.step = step + 1
        result["num_gaussians"] = float(self.model.num_gaussians)
        result.update(self.step_summary(step))
        return result

    def _unscale_gradients(self, means2d_grad: torch.Tensor | None) -> bool:
        """Undo fp16 loss scaling on every gradient the step uses (the optimisers' and the 2D-mean
        gradient that density control reads) and adjust the scale; True when they are all finite."""
        params = [
            p
            for optimizer in self.optimizers
            for group in optimizer.param_groups
            for p in group["params"]
        ]
        finite = self.loss_scaler.unscale([*(p.grad for p in params), means2d_grad])
        self.loss_scaler.update(finite)
        return finite

    @property
    def num_gaussians(self) -> int | None:
        return self.model.num_gaussians if hasattr(self, "model") else None

    def backends(self) -> dict[str, str]:
        """The shared stages' backends on the method's device (float32, as the methods train), and
        the precision of the per-Gaussian networks (``network_precision``) for the methods that have
        them."""
        stages = stage_backends(self.device)
        if hasattr(self.config, "network_precision"):
            stages["network_precision"] = self.config.network_precision
        return stages

    # -------------------------------------------------------------------------------------
    # checkpoints
    def module_state(self) -> dict[str, Any]:
        """The state of the method's modules (shader, refinements), saved beside the model
        (default: none)."""
        return {}

    def load_module_state(self, state: dict[str, Any]) -> None:
        """Restore what `module_state` saved (default: nothing)."""

    def state_dict(self) -> dict[str, Any]:
        state: dict[str, Any] = {
            "format": self.state_format,
            "step": self.step,
            "config": self.config.to_dict(),
            "frame": self.frame.to_dict(),
            "model": self.model.state_dict(),
            **self.module_state(),
            "gaussian_optimizer": self.gaussian_optimizer.state_dict(),
        }
        if self.global_optimizer is not None:
            state["global_optimizer"] = self.global_optimizer.state_dict()
        state.update(
            {
                "densifier": self.densifier.state_dict(),
                "views": self.train_views.state_dict(),
                "torch_rng": torch.get_rng_state(),
            }
        )
        if self.loss_scaler is not None:
            state["loss_scaler"] = self.loss_scaler.state_dict()
        return state

    def check_state(self, state: Any) -> None:
        """A `ValueError` unless ``state`` is this method's checkpoint format, written with this
        config. A field the checkpoint does not list (one added to the config after it was written)
        counts as written at its default, the behaviour the code had before the field existed."""
        found = state.get("format") if isinstance(state, dict) else type(state).__name__
        if found != self.state_format:
            raise ValueError(
                f"not a {self.label} checkpoint (format {found!r}, need {self.state_format!r})"
            )
        config = self.config.to_dict()
        defaults = type(self.config)().to_dict()
        written = state["config"]
        changed = sorted(
            k
            for k in set(written) | set(config)
            if written.get(k, defaults.get(k)) != config.get(k)
        )
        if changed:
            raise ValueError(
                f"{self.label} checkpoint was written with a different config (fields: "
                f"{', '.join(changed)})"
            )

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a `state_dict` (call `setup` with the same views first)."""
        self.check_state(state)
        frame = Similarity.from_dict(state["frame"]) if "frame" in state else Similarity.identity()
        if not frame.allclose(self.frame):
            raise ValueError(
                f"{self.label} checkpoint was trained in another canonical frame "
                f"({frame.to_dict()}) than these views give ({self.frame.to_dict()}): were the "
                "scene's cameras changed?"
            )
        self.model.load_state_dict(state["model"])
        self.load_module_state(state)
        self._build_optimisers()
        self.gaussian_optimizer.load_state_dict(state["gaussian_optimizer"])
        if self.global_optimizer is not None:
            self.global_optimizer.load_state_dict(state["global_optimizer"])
        self.densifier.load_state_dict(state["densifier"])
        self.train_views.load_state_dict(state["views"])
        torch.set_rng_state(state["torch_rng"])
        if self.loss_scaler is not None:
            self.loss_scaler.load_state_dict(state["loss_scaler"])
        self.step = int(state["step"])
