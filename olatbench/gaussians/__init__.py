"""olatbench.gaussians."""

# Rasterizer (projection, tile binning, compositing backends, one-call render, contribution pass).
from .contribution import Contribution as Contribution
from .contribution import max_weights as max_weights
from .projection import Projected as Projected
from .projection import project as project
from .rasterize import Rasterized as Rasterized
from .rasterize import rasterize as rasterize
from .render import render as render
from .tiles import TileBins as TileBins
from .tiles import bin_gaussians as bin_gaussians

# Training support (parameters, density control, schedules, refinement, light-view shadow pass).
# isort: split
from .densify import Densifier as Densifier
from .densify import DensifyConfig as DensifyConfig
from .lr import exponential_lr as exponential_lr
from .model import GaussianModel as GaussianModel
from .refinement import LightRefinement as LightRefinement
from .refinement import PoseRefinement as PoseRefinement
from .shadow import ShadowResult as ShadowResult
from .shadow import camera_matched_focal as camera_matched_focal
from .shadow import light_camera as light_camera
from .shadow import shadow_gather as shadow_gather
