"""Procedural albedo textures (numpy): written to a bitmap and mapped with the mesh's uv
coordinates."""

from __future__ import annotations

import numpy as np

from olatbench.datasets import portable

TEXTURES = ("checker", "marble")


def procedural_texture(
    name: str, base: tuple[float, float, float], size: int = 256, scale: float = 8.0, seed: int = 0
) -> np.ndarray:
    """Linear-light albedo texture (size, size, 3) float32 in [0.02, 0.9].

    ``checker``: ``scale`` × ``scale`` tiles alternating ``base`` and a complementary tint, softened
    by low-frequency noise; ``marble``: ``base`` modulated by a sine of noisy stripes. Both are
    periodic in u, so the longitude seam of a sphere-like mesh is invisible. Deterministic in
    ``seed``.
    """
    if name not in TEXTURES:
        raise ValueError(f"unknown texture {name!r}; expected one of {', '.join(TEXTURES)}")
    u, v = np.meshgrid(
        (np.arange(size) + 0.5) / size, (np.arange(size) + 0.5) / size, indexing="xy"
    )
    rng = np.random.default_rng(seed)
    noise = np.zeros_like(u)
    for octave in range(1, 5):  # periodic value noise from random Fourier terms
        for _ in range(3):
            ku, kv = rng.integers(1, 3 * octave, size=2)
            noise += (
                portable.sin(2 * np.pi * (ku * u + kv * v) + rng.uniform(0, 2 * np.pi)) / octave
            )
    noise /= np.max(np.abs(noise))
    base_rgb = np.asarray(base, dtype=np.float64)
    if name == "checker":
        tiles = (np.floor(u * scale) + np.floor(v * scale)) % 2
        other = np.clip(1.0 - base_rgb, 0.05, 0.9) * 0.8
        weight = np.clip(tiles + 0.15 * noise, 0.0, 1.0)[..., None]
        texture = base_rgb * (1.0 - weight) + other * weight
    else:
        stripes = 0.5 + 0.5 * portable.sin(2 * np.pi * scale * (u + 0.15 * noise))
        texture = base_rgb * (0.35 + 0.65 * stripes[..., None])
    return np.clip(texture, 0.02, 0.9).astype(np.float32)
