"""olatbench.gaussians."""

# Rasterizer (projection, tile binning, compositing backends, one-call render).
from .projection import Projected as Projected
from .projection import project as project
from .rasterize import Rasterized as Rasterized
from .rasterize import rasterize as rasterize
from .render import render as render
from .tiles import TileBins as TileBins
from .tiles import bin_gaussians as bin_gaussians
