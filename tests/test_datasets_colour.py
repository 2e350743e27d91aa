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


def _srgb_encode_reference(x: np.ndarray) -> np.ndarray:
    x = np.clip(x.astype(np.float64), 0, None)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def _srgb_decode_reference(x: np.ndarray) -> np.ndarray:
    x = np.clip(x.astype(np.float64), 0, None)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


@pytest.mark.parametrize(
    ("function", "reference"),
    [
        (colour.gamma_encode, lambda x: np.clip(x.astype(np.float64), 0, None) ** (1 / 2.2)),
        (colour.gamma_decode, lambda x: np.clip(x.astype(np.float64), 0, None) ** 2.2),
        (colour.linear_to_srgb, _srgb_encode_reference),
        (colour.srgb_to_linear, _srgb_decode_reference),
    ],
)
def test_transfer_functions_match_float64_closed_forms(function, reference):
    """Over 1e-5 … 1e2 (both sides of the sRGB knee), clamping negatives, keeping 0, inf and NaN."""
    x = np.concatenate([np.logspace(-5, 2, 20_001), [0.0, -0.5, 0.0031308, 0.04045]]).astype(
        np.float32
    )
    y = function(x)
    assert y.dtype == np.float32
    np.testing.assert_allclose(y, reference(x), rtol=4e-6, atol=1e-12)
    special = function(np.array([np.inf, np.nan], dtype=np.float32))
    assert special[0] == np.inf and np.isnan(special[1])


@pytest.mark.parametrize(
    ("source", "target"),
    [
        ("linear", "gamma22"),
        ("linear", "srgb"),
        ("srgb", "linear"),
        ("gamma22", "srgb"),
        ("srgb", "srgb"),
    ],
)
def test_convert_in_place_equals_a_fresh_result(source, target):
    """``out=`` the input itself, contiguous or a strided RGB view of an RGBA buffer, changes
    nothing else."""
    rgba = np.random.default_rng(1).uniform(-0.1, 1.5, (6, 5, 4)).astype(np.float32)
    expected = colour.convert_colourspace(rgba[..., :3], source, target)
    # same space: no copy, as documented
    assert source == target or not np.shares_memory(expected, rgba)
    strided = rgba.copy()
    result = colour.convert_colourspace(strided[..., :3], source, target, out=strided[..., :3])
    np.testing.assert_array_equal(result, expected)
    np.testing.assert_array_equal(strided[..., :3], expected)
    np.testing.assert_array_equal(strided[..., 3], rgba[..., 3])  # alpha untouched
    packed = np.ascontiguousarray(rgba[..., :3])
    assert colour.convert_colourspace(packed, source, target, out=packed) is packed
    np.testing.assert_array_equal(packed, expected)


def test_composite_in_place_on_a_strided_view():
    rgba = np.random.default_rng(2).uniform(0, 1, (4, 3, 4)).astype(np.float32)
    expected = colour.composite(
        rgba[..., :3], rgba[..., 3], np.array([1.0, 0.5, 0.25]), "premultiplied"
    )
    buffer = rgba.copy()
    colour.composite(
        buffer[..., :3],
        buffer[..., 3],
        np.array([1.0, 0.5, 0.25]),
        "premultiplied",
        out=buffer[..., :3],
    )
    np.testing.assert_array_equal(buffer[..., :3], expected)
    np.testing.assert_array_equal(buffer[..., 3], rgba[..., 3])
