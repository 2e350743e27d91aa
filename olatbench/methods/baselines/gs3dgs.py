"""Vanilla 3D Gaussian Splatting (Kerbl et al. 2023): the light-unaware lower bound of the paper's
tables.

Colour is view-dependent spherical harmonics of degree 3 (`olatbench.methods.baselines.sh`), raised
one degree every ``sh_increase_interval`` steps; the light of a view is ignored, so one radiance
field has to explain every lighting at once and novel lights are not reproduced. Training is the
3DGS recipe on the shared core: one view per step, ``0.8 L1 + 0.2 (1 - SSIM)``, Adam (eps 1e-15)
with the exponential position rate, and 3DGS density control
(`olatbench.gaussians.densify.Densifier`). Gaussians start uniformly in a ball (the OLAT datasets
have no SfM points), as SSD-GS does.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar

import torch

from olatbench.gaussians.lr import exponential_lr
from olatbench.gaussians.projection import project
from olatbench.gaussians.rasterize import rasterize
from olatbench.methods.baselines import sh
from olatbench.methods.baselines.gs3dgs_config import GS3DConfig
from olatbench.methods.baselines.gs3dgs_spec import PRESETS, SPEC
from olatbench.methods.gaussian_method import GaussianMethod, SplatColour
from olatbench.methods.training import camera_centre, camera_tensors

if TYPE_CHECKING:
    from olatbench.datasets.records import Camera, PointLight

# 2: the optimiser saved as "gaussian_optimizer"
STATE_FORMAT = "olatbench.methods.baselines.3dgs/2"


class GaussianSplatting3D(GaussianMethod, spec=SPEC):
    """3DGS with degree-3 SH colour, unaware of the light (the paper's lower bound)."""

    config_class: ClassVar[type] = GS3DConfig
    state_format: ClassVar[str] = STATE_FORMAT
    label: ClassVar[str] = "3DGS"

    config: GS3DConfig

    # -------------------------------------------------------------------------------------------
    # set-up
    @classmethod
    def splat_colour(cls, attributes: Mapping[str, torch.Tensor], colourspace: str) -> SplatColour:
        """The trained SH coefficients as they are (3DGS's own colour; in the job's
        ``colourspace``)."""
        return SplatColour(
            attributes["sh_dc"].reshape(-1, 3),
            attributes["sh_rest"],
            ("sh_dc", "sh_rest"),
            f"colour: 3DGS spherical harmonics as trained ({colourspace} radiance)",
        )

    def initial_attributes(self, n: int) -> dict[str, torch.Tensor]:
        rest = sh.num_coefficients(self.config.sh_degree) - 1
        return {
            "sh_dc": torch.zeros(n, 1, 3, device="cpu"),
            "sh_rest": torch.zeros(n, rest, 3, device="cpu"),
        }

    def learning_rates(self, step: int) -> dict[str, float]:
        """Per parameter group at ``step``: exponential decay for positions, constants otherwise
        (3DGS)."""
        cfg = self.config
        extent = self.train_views.scene_extent
        return {
            "means": exponential_lr(
                step,
                cfg.position_lr_init * extent,
                cfg.position_lr_final * extent,
                max(1, cfg.steps(cfg.position_lr_max_steps)),
            ),
            "log_scales": cfg.scaling_lr,
            "quats": cfg.rotation_lr,
            "opacity_logits": cfg.opacity_lr,
            "attributes.sh_dc": cfg.feature_lr,
            "attributes.sh_rest": cfg.feature_lr / 20.0,
        }

    def active_sh_degree(self, step: int) -> int:
        """SH degree in use at ``step``: one more every ``sh_increase_interval`` steps, up to
        ``sh_degree``."""
        return min(self.config.sh_degree, step // self.config.sh_increase_interval)

    # ------------------------------------------------------------------------------------- forward
    # pass
    def _forward(
        self, w2c: torch.Tensor, K: torch.Tensor, width: int, height: int, degree: int
    ) -> dict[str, Any]:
        model = self.model
        projected = project(model.means, model.quats, model.scales, w2c, K, width, height)
        dirs = torch.nn.functional.normalize(model.means - camera_centre(w2c)[None, :], dim=-1)
        coefficients = torch.cat([model.attributes["sh_dc"], model.attributes["sh_rest"]], dim=1)
        colours = (sh.eval_sh(degree, coefficients, dirs) + 0.5).clamp_min(0.0)
        out = rasterize(projected, model.opacities, colours, self.train_views.background)
        return {
            "image": out.image,
            "alpha": out.alpha,
            "projected": projected,
            "light_weight": None,
        }

    def training_forward(self, index: int, step: int) -> dict[str, Any]:
        views = self.train_views
        camera = views.views.cameras[index]
        return self._forward(
            views.w2cs[index],
            views.Ks[index],
            camera.width,
            camera.height,
            self.active_sh_degree(step),
        )

    def step_summary(self, step: int) -> dict[str, float]:
        return {"sh_degree": float(self.active_sh_degree(step))}

    # -----------------------------------------------------------------------------------------
    # rendering
    @torch.no_grad()
    def render_canonical(self, camera: Camera, light: PointLight) -> dict[str, torch.Tensor]:
        """``rgb`` (H, W, 3) in [0, 1] and the coverage ``alpha`` (H, W, 1); ``light`` is ignored
        (3DGS has no notion of it)."""
        w2c, K = camera_tensors(camera, self.device)
        out = self._forward(
            w2c, K, camera.width, camera.height, self.active_sh_degree(max(self.step - 1, 0))
        )
        return {"rgb": out["image"].clamp(0.0, 1.0), "alpha": out["alpha"][..., None]}


__all__ = ["PRESETS", "GS3DConfig", "GaussianSplatting3D"]
