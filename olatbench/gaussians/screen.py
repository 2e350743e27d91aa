"""Screen-space conventions the torch reference and the native backends share: the tile size and the
tile bins (`olatbench.gaussians.tiles`), the cut-off radius and the frustum clamp of the projection
(`olatbench.gaussians.projection`). A leaf of the Gaussian core (torch only), so the backends read
them without importing the modules that dispatch to the backends.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

# 3DGS clamps x/z and y/z of the camera-space mean to 1.3 × the half-FoV tangent before building the
# Jacobian, so that Gaussians far outside the frustum do not get huge screen-space footprints.
FRUSTUM_CLAMP = 1.3
# Gaussians are cut off at 3 standard deviations along their major axis.
RADIUS_SIGMAS = 3.0
#: Tiles are TILE_SIZE × TILE_SIZE pixel squares from the image's top-left corner.
TILE_SIZE = 16


@dataclass
class TileBins:
    """Per-tile, depth-sorted Gaussian lists.

    ``offsets`` (tiles_y·tiles_x + 1,) int64 and ``gaussian_ids`` (M,) int64: tile
    ``t = ty·tiles_x + tx`` holds ``gaussian_ids[offsets[t]:offsets[t+1]]``, nearest first. Tiles
    are ``tile_size`` px squares from the top-left corner; the last row/column may extend beyond the
    image.
    """

    offsets: torch.Tensor
    gaussian_ids: torch.Tensor
    tile_size: int
    tiles_x: int
    tiles_y: int
    width: int
    height: int

    @property
    def num_tiles(self) -> int:
        return self.tiles_x * self.tiles_y

    @property
    def num_pairs(self) -> int:
        return int(self.gaussian_ids.numel())


def frustum_clamp_bounds(K: torch.Tensor, width: int, height: int) -> torch.Tensor:
    """(u_lo, u_hi, v_lo, v_hi) as a (4,) float64 tensor on ``K``'s device: the range of x/z and y/z
    the Jacobian is evaluated in — the image edges plus (FRUSTUM_CLAMP - 1) × the half-FoV tangent
    on each side. Computed on the device (no host read of ``K``) in float64, with the operations and
    their order of the float arithmetic it replaces, so the bounds are bitwise those of Python
    floats."""
    k = K.detach().double()
    fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2], k[1, 2]
    pad_x = torch.full_like(fx, (FRUSTUM_CLAMP - 1.0) * 0.5 * width) / fx
    pad_y = torch.full_like(fy, (FRUSTUM_CLAMP - 1.0) * 0.5 * height) / fy
    return torch.stack(
        [-cx / fx - pad_x, (width - cx) / fx + pad_x, -cy / fy - pad_y, (height - cy) / fy + pad_y]
    )
