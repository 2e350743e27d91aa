"""A trained-looking stand-in model: the Gaussians as a closed, nearly opaque surface.

Training turns SSD-GS's initial cloud (uniform in a ball, opacity 0.1: every pixel blends many
Gaussians) into flat, mostly opaque Gaussians on the object's surface (a pixel terminates after a
few), which steps 2–2.5× faster at the same count on the mini scenes
(measured 2026-11-25, `olatbench.bench.estimate`). The step cost of a model is therefore timed on
this stand-in (the calibration, ``benchmarks/bench_ssdgs.py``'s ``surface`` state and
``bench_scale.py``), not on the initial cloud.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch

from olatbench.gaussians.model import GaussianModel

#: The stand-in's opacity: most pixels terminate after a few Gaussians, as on a trained model.
SURFACE_OPACITY = 0.9


def place_on_sphere(
    model: GaussianModel,
    centre: Sequence[float],
    radius: float,
    opacity: float = SURFACE_OPACITY,
    seed: int = 0,
) -> None:
    """Make ``model`` a closed surface in place: its N Gaussians at uniform random points of the
    sphere (``centre`` (3,), ``radius``, world units), flat along the normal (tangent scales √(area
    / N), the normal one 0.1× that), all at ``opacity``. Other attributes are left as they are."""
    n = model.num_gaussians
    device = model.means.device
    generator = torch.Generator().manual_seed(seed)  # on the CPU: the same points on every device
    normals = torch.nn.functional.normalize(
        torch.randn(n, 3, generator=generator, device="cpu").to(device), dim=-1
    )
    tangent_scale = math.sqrt(4.0 * math.pi * radius**2 / n)
    # the rotation taking +z to the normal: axis z × n, angle acos(z·n), as a wxyz quaternion
    z = torch.tensor([0.0, 0.0, 1.0], device=device)
    half = torch.nn.functional.normalize(normals + z, dim=-1)
    quats = torch.cat([half[:, 2:3], torch.linalg.cross(z.expand(n, 3), half)], dim=1)
    with torch.no_grad():
        model.means.copy_(
            normals * radius + torch.as_tensor(centre, dtype=model.means.dtype, device=device)
        )
        model.quats.copy_(quats)
        scales = torch.tensor([tangent_scale, tangent_scale, 0.1 * tangent_scale], device=device)
        model.log_scales.copy_(torch.log(scales))
        model.opacity_logits.fill_(math.log(opacity / (1.0 - opacity)))
