"""Vanilla 3D Gaussian Splatting (Kerbl et al. 2023): the light-unaware lower bound of the paper's tables.

Colour is view-dependent spherical harmonics of degree 3 (`olatbench.methods.baselines.sh`), raised one degree
every ``sh_increase_interval`` steps; the light of a view is ignored, so one radiance field has to explain every
lighting at once and novel lights are not reproduced. Training is the 3DGS recipe on the shared core: one view
per step, ``0.8 L1 + 0.2 (1 - SSIM)``, Adam (eps 1e-15) with the exponential position rate, and 3DGS density
control (`olatbench.gaussians.densify.Densifier`). Gaussians start uniformly in a ball (the OLAT datasets
have no SfM points), as SSD-GS does.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

import torch

from olatbench.gaussians.lr import exponential_lr
from olatbench.gaussians.optim import make_adam
from olatbench.gaussians.projection import project
from olatbench.gaussians.rasterize import rasterize
from olatbench.methods.base import Method, Views
from olatbench.methods.baselines import sh
from olatbench.methods.baselines.gs3dgs_config import GS3DConfig
from olatbench.methods.baselines.gs3dgs_spec import PRESETS, SPEC
from olatbench.methods.training import (
    TrainingViews,
    camera_centre,
    camera_tensors,
    initial_model,
    make_densifier,
    per_gaussian_groups,
    photometric_loss,
    psnr_of,
)

if TYPE_CHECKING:
    from olatbench.datasets.records import Camera, PointLight

STATE_FORMAT = "olatbench.methods.baselines.3dgs/1"


class GaussianSplatting3D(Method):
    """3DGS with degree-3 SH colour, unaware of the light (the paper's lower bound)."""

    name: ClassVar[str] = "3dgs"
    config_class: ClassVar[type] = GS3DConfig
    presets: ClassVar[dict[str, dict[str, Any]]] = PRESETS
    description: ClassVar[str] = SPEC.description

    def __init__(self, config: GS3DConfig | None = None) -> None:
        super().__init__(config if config is not None else GS3DConfig())
        self.config: GS3DConfig
        self.step = 0

    # ------------------------------------------------------------------------------------------- setup
    def setup(self, train: Views, device: str | torch.device, seed: int) -> None:
        cfg = self.config
        self.device = torch.device(device)
        torch.manual_seed(seed)
        self.train_views = TrainingViews(train, self.device, seed)
        n = cfg.num_init_gaussians
        rest = sh.num_coefficients(cfg.sh_degree) - 1
        attributes = {"sh_dc": torch.zeros(n, 1, 3), "sh_rest": torch.zeros(n, rest, 3)}
        self.model = initial_model(train, cfg, attributes, seed, self.device)
        self._build_optimizer()
        self.densifier = make_densifier(cfg, train.background, seed)
        self.step = 0

    def _build_optimizer(self) -> None:
        self.optimizer = make_adam(per_gaussian_groups(self.model))

    def learning_rates(self, step: int) -> dict[str, float]:
        """Per parameter group at ``step``: exponential decay for positions, constants otherwise (3DGS)."""
        cfg = self.config
        extent = self.train_views.scene_extent
        return {
            "means": exponential_lr(step, cfg.position_lr_init * extent, cfg.position_lr_final * extent,
                                    max(1, cfg.steps(cfg.position_lr_max_steps))),
            "log_scales": cfg.scaling_lr, "quats": cfg.rotation_lr, "opacity_logits": cfg.opacity_lr,
            "attributes.sh_dc": cfg.feature_lr, "attributes.sh_rest": cfg.feature_lr / 20.0,
        }

    def active_sh_degree(self, step: int) -> int:
        """SH degree in use at ``step``: one more every ``sh_increase_interval`` steps, up to ``sh_degree``."""
        return min(self.config.sh_degree, step // self.config.sh_increase_interval)

    # ------------------------------------------------------------------------------------- forward pass
    def _forward(self, w2c: torch.Tensor, K: torch.Tensor, width: int, height: int, degree: int) -> dict[str, Any]:
        model = self.model
        projected = project(model.means, model.quats, model.scales, w2c, K, width, height)
        dirs = torch.nn.functional.normalize(model.means - camera_centre(w2c)[None, :], dim=-1)
        coefficients = torch.cat([model.attributes["sh_dc"], model.attributes["sh_rest"]], dim=1)
        colours = (sh.eval_sh(degree, coefficients, dirs) + 0.5).clamp_min(0.0)
        out = rasterize(projected, model.opacities, colours, self.train_views.background)
        return {"image": out.image, "projected": projected}

    # ------------------------------------------------------------------------------------------ training
    def train_step(self, step: int) -> dict[str, float]:
        for group in self.optimizer.param_groups:
            group["lr"] = self.learning_rates(step)[group["name"]]
        views = self.train_views
        index = views.next_index()
        camera = views.views.cameras[index]
        out = self._forward(views.w2cs[index], views.Ks[index], camera.width, camera.height,
                            self.active_sh_degree(step))
        image = out["image"].clamp(0.0, 1.0)
        target = views.image(index)
        loss, l1 = photometric_loss(image, target, self.config.lambda_dssim)
        projected = out["projected"]
        projected.means2d.retain_grad()
        loss.backward()
        self.optimizer.step()
        self.optimizer.zero_grad(set_to_none=True)
        self.densifier.observe_and_step(self.model, self.optimizer, projected, step, views.scene_extent)
        self.step = step + 1
        return {"loss": float(loss.detach()), "l1": float(l1.detach()), "psnr": psnr_of(image, target),
                "num_gaussians": float(self.model.num_gaussians), "sh_degree": float(self.active_sh_degree(step))}

    # ----------------------------------------------------------------------------------------- rendering
    @torch.no_grad()
    def render(self, camera: Camera, light: PointLight) -> dict[str, torch.Tensor]:
        """``rgb`` (H, W, 3) in [0, 1]; ``light`` is ignored (3DGS has no notion of it)."""
        w2c, K = camera_tensors(camera, self.device)
        out = self._forward(w2c, K, camera.width, camera.height, self.active_sh_degree(max(self.step - 1, 0)))
        return {"rgb": out["image"].clamp(0.0, 1.0)}

    @property
    def num_gaussians(self) -> int | None:
        return self.model.num_gaussians if hasattr(self, "model") else None

    # ----------------------------------------------------------------------------------------- checkpoints
    def state_dict(self) -> dict[str, Any]:
        return {"format": STATE_FORMAT, "step": self.step, "config": self.config.to_dict(),
                "model": self.model.state_dict(), "optimizer": self.optimizer.state_dict(),
                "densifier": self.densifier.state_dict(), "views": self.train_views.state_dict(),
                "torch_rng": torch.get_rng_state()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a `state_dict` (call `setup` with the same views first)."""
        found = state.get("format") if isinstance(state, dict) else type(state).__name__
        if found != STATE_FORMAT:
            raise ValueError(f"not a 3DGS checkpoint (format {found!r}, need {STATE_FORMAT!r})")
        if state["config"] != self.config.to_dict():
            changed = sorted(k for k, v in state["config"].items() if self.config.to_dict().get(k) != v)
            raise ValueError(f"3DGS checkpoint was written with a different config (fields: {', '.join(changed)})")
        self.model.load_state_dict(state["model"])
        self._build_optimizer()
        self.optimizer.load_state_dict(state["optimizer"])
        self.densifier.load_state_dict(state["densifier"])
        self.train_views.load_state_dict(state["views"])
        torch.set_rng_state(state["torch_rng"])
        self.step = int(state["step"])


__all__ = ["PRESETS", "GS3DConfig", "GaussianSplatting3D"]
