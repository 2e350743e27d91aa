"""colour.composite / gamma_encode after the in-place rewrite: closed forms, dtypes, no aliasing."""

from __future__ import annotations

import numpy as np
import pytest

from olatbench.datasets import colour


@pytest.mark.parametrize("background", [0.0, 0.25, np.array([1.0, 0.5, 0.0]), "image"])
@pytest.mark.parametrize("mode", ["straight", "premultiplied"])
def test_composite_closed_form(background, mode):
    rng = np.random.default_rng(0)
    rgba = rng.uniform(0, 1, (5, 7, 4)).astype(np.float32)
    rgb, alpha = rgba[..., :3], rgba[..., 3]  # a strided view, as Frame.load passes it
    bg = rng.uniform(0, 1, (5, 7, 3)) if isinstance(background, str) else background
    a = alpha[..., None].astype(np.float64)
    fg = rgb * a if mode == "straight" else rgb
    expected = fg + np.asarray(bg, dtype=np.float64) * (1 - a)
    out = colour.composite(rgb, alpha, bg, mode)
    assert out.dtype == np.float32 and out.shape == (5, 7, 3)
    np.testing.assert_allclose(out, expected, rtol=1e-6, atol=1e-7)
    out[...] = -1  # the result never aliases the input
    assert np.all(rgba >= 0)


def test_gamma_encode_is_float32_power():
    x = np.array([0.0, 0.25, 1.0, 4.0, -1.0], dtype=np.float32)
    y = colour.gamma_encode(x)
    assert y.dtype == np.float32
    np.testing.assert_allclose(y, np.clip(x, 0, None).astype(np.float64) ** (1 / 2.2), rtol=1e-6)
