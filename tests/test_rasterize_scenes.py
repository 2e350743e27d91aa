"""Small random Gaussian scenes shared by the rasterizer and projection tests
(helpers only, no tests)."""

from __future__ import annotations

import torch


def camera(width: int, height: int, focal: float = 40.0, dtype: torch.dtype = torch.float64):
    """A camera at the origin looking down +z (OpenCV axes): (w2c, K)."""
    K = torch.tensor(
        [[focal, 0.0, width / 2.0], [0.0, focal * 1.05, height / 2.0], [0.0, 0.0, 1.0]], dtype=dtype
    )
    angle = torch.tensor(0.05, dtype=dtype)
    w2c = torch.eye(4, dtype=dtype)
    w2c[0, 0], w2c[0, 2], w2c[2, 0], w2c[2, 2] = angle.cos(), angle.sin(), -angle.sin(), angle.cos()
    w2c[:3, 3] = torch.tensor([0.02, -0.03, 0.1], dtype=dtype)
    return w2c, K


def scene(
    n: int,
    channels: int = 3,
    seed: int = 0,
    spread: float = 0.5,
    scale: tuple[float, float] = (0.03, 0.12),
    opacity: tuple[float, float] = (0.2, 0.85),
    depth: float = 3.0,
    dtype: torch.dtype = torch.float64,
) -> dict[str, torch.Tensor]:
    """Random Gaussians in front of ``camera``: means, quats, scales, opacities, features,
    background."""
    g = torch.Generator().manual_seed(seed)
    means = (torch.rand(n, 3, generator=g, dtype=dtype) * 2 - 1) * spread
    means[:, 2] += depth
    return {
        "means": means,
        "quats": torch.randn(n, 4, generator=g, dtype=dtype) * 1.7,
        "scales": scale[0] + torch.rand(n, 3, generator=g, dtype=dtype) * (scale[1] - scale[0]),
        "opacities": opacity[0]
        + torch.rand(n, generator=g, dtype=dtype) * (opacity[1] - opacity[0]),
        "features": torch.rand(n, channels, generator=g, dtype=dtype),
        "background": torch.rand(channels, generator=g, dtype=dtype),
    }
