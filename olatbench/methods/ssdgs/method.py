"""SSD-GS (ICLR 2026): relightable Gaussians with diffuse, specular, dipole-SSS and refined-shadow
terms.

The runner owns the loop; this class answers `setup`, `train_step`, `render`, `state_dict` and
`load_state_dict`. One training step: pick a training view (a fresh random permutation each epoch),
project the Gaussians, shade only the visible ones (radii > 0; with ``cull_shading`` only those
whose largest blending weight in the view exceeds ``cull_epsilon``) with the terms the schedule has
switched on, splat the colour as 3 feature channels, take ``0.8 L1 + 0.2 (1 - SSIM)``, step Adam
(per-Gaussian parameters and global parameters in two optimisers so densification surgery only
touches the former), then densify as 3DGS.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import torch
import torch.nn.functional as F

from olatbench.gaussians.lr import exponential_lr
from olatbench.gaussians.optim import make_adam
from olatbench.gaussians.projection import project
from olatbench.gaussians.rasterize import rasterize
from olatbench.gaussians.refinement import LightRefinement, PoseRefinement
from olatbench.gaussians.shadow import shadow_gather
from olatbench.methods.base import Views
from olatbench.methods.evaluation_protocol import RefinedView
from olatbench.methods.gaussian_method import (
    GaussianMethod,
    ParameterGroup,
    SplatColour,
    albedo_splat_colour,
)
from olatbench.methods.shading.light_view import light_view_options
from olatbench.methods.ssdgs.config import SSDGSConfig
from olatbench.methods.ssdgs.schedule import Schedule
from olatbench.methods.ssdgs.shader import Components, Shader
from olatbench.methods.ssdgs.spec import SPEC
from olatbench.methods.ssdgs.view_fitting import InterleavedFit, view_key
from olatbench.methods.training import (
    camera_centre,
    camera_tensors,
    light_tensors,
    shaded_intensity,
    shaded_subset,
)

if TYPE_CHECKING:
    from olatbench.datasets.records import Camera, PointLight

# 2: view order kept by TrainingViews; 3: near-cap flag, test-view fits
STATE_FORMAT = "olatbench.methods.ssdgs/3"
COMPONENT_CHANNELS = (
    ("rgb", 3),
    ("diffuse", 3),
    ("specular", 3),
    ("sss", 3),
    ("shadow", 1),
    ("shadow_coarse", 1),
)


class SSDGS(GaussianMethod, spec=SPEC):
    """Subsurface scattering, shadow and specular decomposition in Gaussian splatting
    (reference method)."""

    config_class: ClassVar[type] = SSDGSConfig

    state_format: ClassVar[str] = STATE_FORMAT
    label: ClassVar[str] = "SSD-GS"

    config: SSDGSConfig
    _test_views: Views | None = None  # for test_pose_fitting="interleaved" (`attach_test_views`)

    # -------------------------------------------------------------------------------------------
    # setup
    def prepare(self, train: Views) -> None:
        cfg = self.config
        background = np.asarray(train.background, dtype=np.float32).reshape(3)
        if cfg.background is not None and not np.allclose(cfg.background, background, atol=1e-3):
            raise ValueError(
                f"SSD-GS: the config's background {tuple(cfg.background)} differs from the "
                f"training views' {tuple(background.tolist())}; the images are composited on the "
                "latter"
            )
        self.background = torch.as_tensor(background, device=self.device)
        self.schedule: Schedule = cfg.resolved_schedule()
        self.refine_from = cfg.refinement_starts()
        # official `prune_visibility`: a densification left > 95 % of max_gaussians
        self.near_cap = False
        self.terms_in_model = frozenset(
            t
            for t, on in (
                ("shadow", cfg.use_shadow),
                ("sss", cfg.use_sss),
                ("specular", cfg.use_specular),
            )
            if on
        )
        pairs = zip(train.cameras, train.lights, strict=True)
        self._train_keys = {view_key(c, lt): i for i, (c, lt) in enumerate(pairs)}

    @classmethod
    def splat_colour(cls, attributes: Mapping[str, torch.Tensor], colourspace: str) -> SplatColour:
        """The diffuse albedo as a degree-0 SH colour (`albedo_splat_colour`)."""
        return albedo_splat_colour(attributes["diffuse"], colourspace)

    def initial_attributes(self, n: int) -> dict[str, torch.Tensor]:
        cfg = self.config
        # raw; softplus(0.5) = 0.97 as in the official code
        colour = torch.full((n, 3), 0.5, device="cpu")
        attributes = {
            "diffuse": colour,
            "specular": colour.clone(),
            "sss": colour.clone(),
            "asg_weights": torch.zeros(n, cfg.num_asg, device="cpu"),
            "material": torch.ones(n, cfg.material_dim, device="cpu"),
        }
        if cfg.shading_frame == "learned":
            quat = torch.zeros(n, 4, device="cpu")
            quat[:, 0] = 1.0
            attributes["shading_quat"] = quat
        return attributes

    def build_modules(self, train: Views) -> None:
        cfg = self.config
        # random orientations: isotropic identity-rotated Gaussians would share one normal
        with torch.no_grad():
            random = torch.randn(
                self.model.num_gaussians, 4, generator=self.train_views.generator, device="cpu"
            )
            self.model.quats.copy_(F.normalize(random, dim=-1).to(self.device))
        self.shader = Shader(cfg).to(self.device)
        self.pose_refinement = (
            PoseRefinement(len(train), self.device) if cfg.refine_camera else None
        )
        self.light_refinement = (
            LightRefinement(len(train), self.device) if cfg.refine_light else None
        )
        # the test views in the training views' canonical frame (whatever frame the caller attached
        # them with)
        test = (
            replace(self._test_views, frame=self.frame).in_frame()
            if cfg.test_pose_fitting == "interleaved" and self._test_views is not None
            else None
        )
        self.test_fit = (
            InterleavedFit(test, cfg, self.device, self.train_views.generator.initial_seed())
            if test is not None and len(test) > 0
            else None
        )

    def global_groups(self) -> list[ParameterGroup]:
        cfg = self.config
        groups = [
            ParameterGroup("asg_lobes", list(self.shader.asg.parameters()), cfg.asg_lr_init),
            ParameterGroup("sss_mlp", list(self.shader.sss_net.parameters()), cfg.mlp_lr_init),
            ParameterGroup(
                "shadow_mlp", list(self.shader.shadow_net.parameters()), cfg.mlp_lr_init
            ),
        ]
        if self.pose_refinement is not None:
            groups.append(ParameterGroup("camera", list(self.pose_refinement.parameters())))
        if self.light_refinement is not None:
            groups.append(ParameterGroup("light", list(self.light_refinement.parameters())))
        return groups

    # ---------------------------------------------------------------------------------------
    # schedules
    def learning_rates(self, step: int) -> dict[str, float]:
        """Per parameter-group name at ``step``."""
        cfg, s = self.config, self.config.steps

        def decayed(init: float, final: float, start: int, length: int) -> float:
            return exponential_lr(max(0, step - s(start)), init, final, max(1, s(length)))

        asg = decayed(
            cfg.asg_lr_init, cfg.asg_lr_final, cfg.asg_lr_decay_from, cfg.asg_lr_max_steps
        )
        mlp = decayed(
            cfg.mlp_lr_init, cfg.mlp_lr_final, cfg.mlp_lr_decay_from, cfg.mlp_lr_max_steps
        )
        refine_length = max(1, s(cfg.refinement_lr_max_steps))

        def refinement(
            init: float, final: float, start: int, delay_steps: int, delay_mult: float
        ) -> float:
            if step < start:
                return 0.0
            clock = step if cfg.refinement_lr_clock == "absolute" else step - start
            return exponential_lr(clock, init, final, refine_length, s(delay_steps), delay_mult)

        return {
            "means": exponential_lr(
                step,
                cfg.position_lr_init * self.train_views.scene_extent,
                cfg.position_lr_final * self.train_views.scene_extent,
                max(1, s(cfg.position_lr_max_steps)),
            ),
            "log_scales": cfg.scaling_lr,
            "quats": cfg.rotation_lr,
            "opacity_logits": cfg.opacity_lr,
            "attributes.diffuse": cfg.colour_lr,
            "attributes.specular": cfg.colour_lr,
            "attributes.sss": cfg.colour_lr,
            "attributes.asg_weights": asg,
            "attributes.shading_quat": asg,
            "attributes.material": mlp,
            "asg_lobes": asg,
            "sss_mlp": mlp,
            "shadow_mlp": mlp,
            "camera": refinement(
                cfg.camera_lr_init,
                cfg.camera_lr_final,
                self.refine_from["camera"],
                cfg.camera_lr_delay_steps,
                cfg.camera_lr_delay_mult,
            ),
            "light": refinement(
                cfg.light_lr_init,
                cfg.light_lr_final,
                self.refine_from["light"],
                cfg.light_lr_delay_steps,
                cfg.light_lr_delay_mult,
            ),
        }

    def active_terms(self, step: int) -> frozenset[str]:
        """Terms of the model's composition that the schedule has switched on at ``step``."""
        return frozenset(t for t in self.terms_in_model if self.schedule.is_enabled(t, step))

    def frozen_parameters(self, step: int) -> list[torch.nn.Parameter]:
        """Parameters held fixed at ``step`` by the schedule (their gradients are dropped before the
        update)."""
        groups = {
            "shadow_mlp": list(self.shader.shadow_net.parameters()),
            "sss_mlp": list(self.shader.sss_net.parameters()),
            "asg_lobes": self.shader.asg.lobe_parameters(
                include_sigma=self.config.asg_freeze_sigma
            ),
            "material": [self.model.attributes["material"]],
            "specular": [self.model.attributes["specular"], self.model.attributes["asg_weights"]],
        }
        return [
            p
            for group, params in groups.items()
            if self.schedule.is_frozen(group, step)
            for p in params
        ]

    # ------------------------------------------------------------------------------------- forward
    # pass
    def _camera(self, index: int | None, w2c: torch.Tensor, step: int) -> torch.Tensor:
        if (
            index is not None
            and self.pose_refinement is not None
            and step >= self.refine_from["camera"]
        ):
            return self.pose_refinement.apply(index, w2c)
        return w2c

    def _light(self, index: int | None, position: torch.Tensor, step: int) -> torch.Tensor:
        if (
            index is not None
            and self.light_refinement is not None
            and step >= self.refine_from["light"]
        ):
            return self.light_refinement.apply(index, position)
        return position

    def _forward(
        self,
        w2c: torch.Tensor,
        K: torch.Tensor,
        width: int,
        height: int,
        light_position: torch.Tensor,
        intensity: torch.Tensor,
        step: int,
        components: bool,
    ) -> dict[str, Any]:
        """Project, shade the visible Gaussians (those reaching a pixel, with ``cull_shading``) and
        rasterize: rgb only (training) or every component (evaluation)."""
        model = self.model
        projected = project(model.means, model.quats, model.scales, w2c, K, width, height)
        visible, bins = shaded_subset(
            projected, model.opacities, self.config.shading_cull_epsilon(components)
        )
        terms = self.active_terms(step)
        shaded, light_weight = self._shade(
            w2c, K, width, height, light_position, intensity, terms, visible.pick
        )
        if components:
            per_gaussian = torch.cat(
                [
                    shaded.colour,
                    shaded.diffuse,
                    shaded.specular,
                    shaded.sss,
                    shaded.shadow,
                    shaded.shadow_coarse,
                ],
                dim=1,
            )
            background = torch.cat(
                [self.background, self.background.new_zeros(per_gaussian.shape[1] - 3)]
            )
        else:
            per_gaussian, background = shaded.colour, self.background
        out = rasterize(
            projected, model.opacities, visible.scatter(per_gaussian), background, bins=bins
        )
        return {
            "image": out.image,
            "alpha": out.alpha,
            "projected": projected,
            "terms": terms,
            "light_weight": light_weight,
        }

    def _shade(
        self,
        w2c: torch.Tensor,
        K: torch.Tensor,
        width: int,
        height: int,
        light_position: torch.Tensor,
        intensity: torch.Tensor,
        terms: frozenset[str],
        pick,
    ) -> tuple[Components, torch.Tensor | None]:
        """The shading of the Gaussians ``pick`` selects (a function of per-Gaussian tensors (N, …)
        -> (M, …)) seen by the camera ``w2c``, ``K`` (the light-view pass frames itself by it) under
        the light; and the light-view weight (None without the shadow term)."""
        model = self.model
        means, quats, scales = model.means, model.quats, model.scales
        coarse, light_weight = None, None
        camera_position = camera_centre(w2c)
        # the light-view pass sees the model as it is: no gradient flows through it
        if "shadow" in terms:
            with torch.no_grad():
                gathered = shadow_gather(
                    means.detach(),
                    quats.detach(),
                    scales.detach(),
                    model.opacities.detach(),
                    light_position.detach(),
                    means.detach().mean(0),
                    **self.light_view_options(K, width, height, camera_position, light_position),
                )
            coarse, light_weight = pick(gathered.visibility), gathered.weight
        attributes = {name: pick(value) for name, value in model.attributes.items()}
        intensity = shaded_intensity(intensity, self.config.ignores_light_intensity)
        shaded: Components = self.shader(
            pick(means),
            pick(quats),
            pick(scales),
            attributes,
            camera_position,
            light_position,
            intensity,
            terms,
            coarse,
        )
        return shaded, light_weight

    def light_view_options(
        self,
        K: torch.Tensor,
        width: int,
        height: int,
        camera_position: torch.Tensor,
        light_position: torch.Tensor,
    ) -> dict[str, Any]:
        """`shadow_gather` options of the light-view pass for a view (K (3, 3), size, camera centre
        (3,)), looking at the Gaussians' mean (`light_view_options`)."""
        return light_view_options(
            self.config,
            K,
            width,
            height,
            camera_position,
            light_position,
            self.model.means.detach().mean(0),
        )

    # ------------------------------------------------------------------------------------------
    # training
    def training_forward(self, index: int, step: int) -> dict[str, Any]:
        views = self.train_views
        camera = views.views.cameras[index]
        w2c = self._camera(index, views.w2cs[index], step)
        light = self._light(index, views.light_positions[index], step)
        out = self._forward(
            w2c,
            views.Ks[index],
            camera.width,
            camera.height,
            light,
            views.light_intensities[index],
            step,
            components=False,
        )
        if self.config.light_weight_accumulation == "near_cap" and not self.near_cap:
            # the official kernel accumulates it only near the cap (`is_train`)
            out["light_weight"] = None
        return out

    @property
    def densify_before_update(self) -> bool:
        return bool(self.config.densify_before_update)

    def after_density_control(self, step: int, report: dict[str, int | bool]) -> None:
        """Track the official ``prune_visibility``: set by a densification that leaves more than 95
        % of ``max_gaussians``, cleared once densification is over."""
        cap = self.config.max_gaussians
        if not self.densifier.active(step + 1):
            self.near_cap = False
        elif report["densified"] and cap is not None and self.model.num_gaussians > 0.95 * cap:
            self.near_cap = True

    def train_step(self, step: int) -> dict[str, Any]:
        """One training step; with interleaved test-view fitting, a pass over the test views first
        whenever a training epoch has just ended (the official code's alternation)."""
        fitted = None
        if (
            self.test_fit is not None
            and step > 0
            and self.train_views.cursor >= len(self.train_views)
        ):
            fitted = self.test_fit.epoch(
                lambda index, w2c, position: self._test_view_loss(index, w2c, position, step),
                self.learning_rates(step),
                self.refine_from,
                step,
            )
        result = super().train_step(step)
        if fitted is not None:
            result["test_fit_loss"] = fitted
        return result

    def clamp_render(self, render: torch.Tensor) -> torch.Tensor:
        """The render the loss sees: clamped to [0, 1] when ``clamp_output``
        (the official code's choice)."""
        return render.clamp(0.0, 1.0) if self.config.clamp_output else render

    def backends(self) -> dict[str, str]:
        return {**super().backends(), "shading": self.shader.backend_for(self.device)}

    # -----------------------------------------------------------------------------------------
    # rendering
    @torch.no_grad()
    def render_canonical(self, camera: Camera, light: PointLight) -> dict[str, torch.Tensor]:
        """Every component at the current step; training views (same pose and light) use their
        refinements, and so do test views fitted by ``test_pose_fitting="interleaved"``."""
        key, step = view_key(camera, light), max(self.step - 1, 0)
        index = self._train_keys.get(key)
        (w2c, K), (position, intensity) = (
            camera_tensors(camera, self.device),
            light_tensors(light, self.device),
        )
        w2c, position = self._camera(index, w2c, step), self._light(index, position, step)
        if index is None and self.test_fit is not None and key in self.test_fit.keys:
            w2c, position = self.test_fit.apply(
                self.test_fit.keys[key], w2c, position, self.refine_from, step
            )
        out = self._forward(
            w2c, K, camera.width, camera.height, position, intensity, step, components=True
        )
        image, result, start = out["image"], {}, 0
        for name, channels in COMPONENT_CHANNELS:
            result[name] = image[..., start : start + channels]
            start += channels
        result["rgb"] = result["rgb"].clamp(0.0, 1.0)
        result["alpha"] = out["alpha"][..., None]
        return result

    @torch.no_grad()
    def colours_under(self, camera: Camera, light: PointLight) -> torch.Tensor:
        """The colour (N, 3) every Gaussian gives the rasterizer in `render` when ``camera`` sees it
        under ``light`` (no refinement applied: the camera and light as given)."""
        f32 = dict(dtype=torch.float32, device=self.device)
        shaded, _ = self._shade(
            torch.as_tensor(camera.w2c(), **f32),
            torch.as_tensor(camera.K, **f32),
            camera.width,
            camera.height,
            torch.as_tensor(light.position, **f32),
            torch.as_tensor(light.intensity, **f32),
            self.active_terms(max(self.step - 1, 0)),
            lambda value: value,
        )
        return shaded.colour

    def refine_view(
        self, camera: Camera, light: PointLight, image: np.ndarray
    ) -> RefinedView | None:
        """Test-time refinement (``test_time_refinement``): fit this view's pose and/or light to
        ``image``.

        Starting from the view's interleaved fit when there is one (`fitted_view`), a fresh zero
        SO3×R3 pose delta and light offset (as in training, per ``refine_camera`` /
        ``refine_light``) take ``test_time_steps`` Adam steps on the training loss at the training
        refinement's initial rates, every other parameter frozen; the iterate with the lowest loss
        is kept. Summary: ``loss_before``/``loss_after`` (of the returned view), ``translation`` and
        ``light_offset`` (world units), ``rotation_deg``.
        """
        cfg = self.config
        if not cfg.test_time_refinement:
            return None
        # in the canonical frame, from the interleaved fit if the view has one
        camera, light = self.fitted_view(*self.canonical_view(camera, light))
        f32 = dict(dtype=torch.float32, device=self.device)
        w2c, K = torch.as_tensor(camera.w2c(), **f32), torch.as_tensor(camera.K, **f32)
        position, intensity = (
            torch.as_tensor(light.position, **f32),
            torch.as_tensor(light.intensity, **f32),
        )
        target = torch.as_tensor(np.ascontiguousarray(image), **f32)
        pose = PoseRefinement(1, self.device) if cfg.refine_camera else None
        offset = LightRefinement(1, self.device) if cfg.refine_light else None
        groups = (
            [{"params": [pose.tangents], "lr": cfg.camera_lr_init}] if pose is not None else []
        ) + ([{"params": [offset.offsets], "lr": cfg.light_lr_init}] if offset is not None else [])
        params = [p for group in groups for p in group["params"]]
        optimizer = make_adam(groups)
        step = max(self.step - 1, 0)
        losses, best = [], (math.inf, [p.detach().clone() for p in params])
        with torch.enable_grad():
            for _ in range(cfg.test_time_steps + 1):  # the last pass only measures the final loss
                out = self._forward(
                    pose.apply(0, w2c) if pose is not None else w2c,
                    K,
                    camera.width,
                    camera.height,
                    offset.apply(0, position) if offset is not None else position,
                    intensity,
                    step,
                    components=False,
                )
                loss = self.loss(out["image"], target)[1]
                losses.append(float(loss.detach()))
                if losses[-1] < best[0]:
                    best = (losses[-1], [p.detach().clone() for p in params])
                if len(losses) > cfg.test_time_steps:
                    break
                for p, grad in zip(params, torch.autograd.grad(loss, params), strict=True):
                    # only the view's own deltas: the model's parameters get no gradient
                    p.grad = grad
                optimizer.step()
        with torch.no_grad():  # the best iterate seen, so refinement never makes a view worse
            for p, kept in zip(params, best[1], strict=True):
                p.copy_(kept)
        delta = pose.delta(0).detach().double().cpu().numpy() if pose is not None else np.eye(4)
        shift = (
            offset.offsets[0].detach().double().cpu().numpy() if offset is not None else np.zeros(3)
        )
        refined_camera = replace(camera, c2w=np.linalg.inv(delta @ camera.w2c()))
        refined_light = replace(
            light, position=np.asarray(light.position, dtype=np.float64) + shift
        )
        return RefinedView(
            *self.world_view(refined_camera, refined_light),
            {
                "steps": float(cfg.test_time_steps),
                "loss_before": losses[0],
                "loss_after": best[0],
                **_offset_summary(delta, shift, self.frame.scale),
            },
        )

    # ------------------------------------------------------------------------------- test-view
    # fitting
    def attach_test_views(self, test: Views) -> None:
        """Give the test views to ``test_pose_fitting="interleaved"`` (call before `setup`; the
        runner does, through `olatbench.methods.ssdgs.evaluation.SSDGSTestViews`). Without them
        (or with the option off) training has no test passes."""
        self._test_views = test

    def _test_view_loss(
        self, index: int, w2c: torch.Tensor, position: torch.Tensor, step: int
    ) -> torch.Tensor:
        """Training loss of test view ``index`` rendered with the given pose and light at
        ``step``."""
        views = self.test_fit.views
        camera = views.views.cameras[index]
        out = self._forward(
            w2c,
            views.Ks[index],
            camera.width,
            camera.height,
            position,
            views.light_intensities[index],
            step,
            components=False,
        )
        return self.loss(out["image"], views.image(index))[1]

    def fitted_view(self, camera: Camera, light: PointLight) -> tuple[Camera, PointLight]:
        """The camera and light a test view is scored with: its interleaved fit, else as given."""
        index = None if self.test_fit is None else self.test_fit.keys.get(view_key(camera, light))
        if index is None:
            return camera, light
        delta, shift = self.test_fit.deltas(index, self.refine_from, max(self.step - 1, 0))
        return (
            replace(camera, c2w=np.linalg.inv(delta @ camera.w2c())),
            replace(light, position=np.asarray(light.position, dtype=np.float64) + shift),
        )

    def fitted_test_views(self) -> dict[str, dict[str, float]] | None:
        """Per test frame id: the fitted ``translation`` (world units), ``rotation_deg`` and
        ``light_offset`` (world units) of ``test_pose_fitting="interleaved"``; None when the option
        is off or had no test views."""
        if self.test_fit is None:
            return None
        step = max(self.step - 1, 0)
        return {
            frame_id: _offset_summary(
                *self.test_fit.deltas(i, self.refine_from, step), self.frame.scale
            )
            for i, frame_id in enumerate(self.test_fit.views.views.frame_ids)
        }

    # -----------------------------------------------------------------------------------------
    # checkpoints
    def module_state(self) -> dict[str, Any]:
        state: dict[str, Any] = {"shader": self.shader.state_dict(), "near_cap": self.near_cap}
        if self.test_fit is not None:
            state["test_fit"] = self.test_fit.state_dict()
        if self.pose_refinement is not None:
            state["pose_refinement"] = self.pose_refinement.state_dict()
        if self.light_refinement is not None:
            state["light_refinement"] = self.light_refinement.state_dict()
        return state

    def load_module_state(self, state: dict[str, Any]) -> None:
        self.shader.load_state_dict(state["shader"])
        self.near_cap = bool(state["near_cap"])
        if self.test_fit is not None:
            self.test_fit.load_state_dict(state["test_fit"])
        if self.pose_refinement is not None:
            self.pose_refinement.load_state_dict(state["pose_refinement"])
        if self.light_refinement is not None:
            self.light_refinement.load_state_dict(state["light_refinement"])


def _offset_summary(delta: np.ndarray, shift: np.ndarray, scale: float) -> dict[str, float]:
    """How far a canonical camera-space delta (4, 4) and light shift (3,) move a view:
    ``translation`` and ``light_offset`` in world units (canonical lengths / the frame's ``scale``),
    ``rotation_deg``."""
    angle = float(np.degrees(np.arccos(np.clip((np.trace(delta[:3, :3]) - 1.0) / 2.0, -1.0, 1.0))))
    return {
        "translation": float(np.linalg.norm(delta[:3, 3])) / scale,
        "rotation_deg": angle,
        "light_offset": float(np.linalg.norm(shift)) / scale,
    }


__all__ = ["SSDGS"]
