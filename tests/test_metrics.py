"""PSNR / SSIM against scikit-image and straightforward torch references; protocol behaviour."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
import torch
import torch.nn.functional as F
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

from olatbench.metrics import get_protocol, protocol_names, psnr, ssim, ssim_loss, ssim_torch
from olatbench.metrics.ssim import gaussian_taps


def pair(shape, seed=0, noise=0.1, dtype=np.float32):
    rng = np.random.default_rng(seed)
    a = rng.random(shape).astype(dtype)
    b = np.clip(a + noise * rng.standard_normal(shape), 0, 1).astype(dtype)
    return a, b


def skimage_ssim(a, b):
    return structural_similarity(
        a,
        b,
        gaussian_weights=True,
        sigma=1.5,
        use_sample_covariance=False,
        data_range=1,
        channel_axis=-1,
    )


@pytest.mark.parametrize("shape", [(11, 11, 3), (23, 40, 3), (64, 80, 3), (97, 61, 1)])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_ssim_matches_scikit_image(shape, dtype):
    a, b = pair(shape, seed=shape[0], dtype=dtype)
    assert abs(ssim(a, b) - skimage_ssim(a, b)) < 1e-5


def test_ssim_structured_images_match_scikit_image():
    y, x = np.mgrid[0:96, 0:128] / 64.0
    a = np.stack([np.sin(3 * x) * 0.5 + 0.5, x % 1, (y * x) % 1], -1).astype(np.float32)
    b = np.clip(a * 0.8 + 0.1 + 0.02 * np.cos(9 * y)[..., None], 0, 1).astype(np.float32)
    assert abs(ssim(a, b) - skimage_ssim(a, b)) < 1e-5
    assert ssim(a, a) == pytest.approx(1.0, abs=1e-6)


def test_ssim_batch_equals_singles_and_accepts_torch():
    a, b = pair((3, 32, 40, 3), seed=4)
    batch = ssim(a, b)
    assert batch.shape == (3,)
    for i in range(3):
        assert batch[i] == pytest.approx(skimage_ssim(a[i], b[i]), abs=1e-5)
    assert ssim(torch.from_numpy(a[0]), torch.from_numpy(b[0])) == pytest.approx(batch[0], abs=1e-7)


def reference_3dgs_ssim(img1, img2):
    """3DGS utils/loss_utils.ssim written out: 2D window, conv2d with zero padding 5, mean of the
    map."""
    channels = img1.shape[0]
    g = torch.tensor(
        [math.exp(-((x - 5) ** 2) / (2 * 1.5**2)) for x in range(11)], dtype=torch.float64
    )
    g = g / g.sum()
    window = (g[:, None] @ g[None, :]).expand(channels, 1, 11, 11).contiguous()
    mu1 = F.conv2d(img1, window, padding=5, groups=channels)
    mu2 = F.conv2d(img2, window, padding=5, groups=channels)
    s11 = F.conv2d(img1 * img1, window, padding=5, groups=channels) - mu1**2
    s22 = F.conv2d(img2 * img2, window, padding=5, groups=channels) - mu2**2
    s12 = F.conv2d(img1 * img2, window, padding=5, groups=channels) - mu1 * mu2
    c1, c2 = 0.01**2, 0.03**2
    return (
        ((2 * mu1 * mu2 + c1) * (2 * s12 + c2)) / ((mu1**2 + mu2**2 + c1) * (s11 + s22 + c2))
    ).mean()


def test_3dgs_ssim_matches_zero_padded_reference():
    a, b = pair((40, 52, 3), seed=7)
    ref = reference_3dgs_ssim(*(torch.from_numpy(x).double().permute(2, 0, 1) for x in (a, b)))
    assert ssim(a, b, variant="3dgs") == pytest.approx(float(ref), abs=1e-6)
    assert abs(ssim(a, b, variant="3dgs") - ssim(a, b)) > 1e-4  # the border treatment matters


def test_gaussian_taps_match_scipy_convention():
    taps = gaussian_taps(dtype=torch.float64)
    x = np.arange(11) - 5
    expected = np.exp(-(x**2) / (2 * 1.5**2))
    np.testing.assert_allclose(taps.numpy(), expected / expected.sum(), rtol=1e-12)


def test_ssim_torch_gradient_matches_finite_differences():
    a, b = pair((1, 16, 15, 2), seed=3, dtype=np.float64)
    x = torch.from_numpy(a).permute(0, 3, 1, 2)
    y = torch.from_numpy(b).permute(0, 3, 1, 2)
    direction = torch.from_numpy(np.random.default_rng(1).standard_normal(x.shape))
    for variant in ("3dgs", "wang"):
        leaf = x.clone().requires_grad_(True)
        ssim_torch(leaf, y, variant=variant).backward()
        eps = 1e-6
        numeric = (
            ssim_torch(x + eps * direction, y, variant=variant)
            - ssim_torch(x - eps * direction, y, variant=variant)
        ) / (2 * eps)
        assert float((leaf.grad * direction).sum()) == pytest.approx(
            float(numeric), rel=1e-6, abs=1e-9
        )


def test_ssim_loss_is_one_minus_ssim_channels_last():
    a, b = pair((2, 20, 24, 3), seed=9)
    pred = torch.from_numpy(a).requires_grad_(True)
    loss = ssim_loss(pred, torch.from_numpy(b), channels_last=True)
    loss.backward()
    assert float(loss.detach()) == pytest.approx(
        1 - float(np.mean(ssim(a, b, variant="3dgs"))), abs=1e-6
    )
    assert pred.grad is not None and torch.isfinite(pred.grad).all()


def test_psnr_matches_scikit_image_and_closed_form():
    a, b = pair((30, 31, 3), seed=1)
    assert psnr(a, b) == pytest.approx(peak_signal_noise_ratio(a, b, data_range=1), abs=1e-4)
    c = np.full((8, 8, 3), 0.5, np.float32)
    assert psnr(c, c + 0.1) == pytest.approx(20.0, abs=1e-4)  # MSE = 0.01


def test_masked_metrics():
    a, b = pair((40, 44, 3), seed=2)
    ones = np.ones((40, 44), np.float32)
    assert psnr(a, b, mask=ones) == pytest.approx(psnr(a, b), abs=1e-5)
    assert ssim(a, b, mask=ones) == pytest.approx(ssim(a, b), abs=1e-6)
    mask = np.zeros((40, 44), np.float32)
    mask[5:30, 8:40] = 1
    inside = ((a - b) ** 2)[mask > 0].mean()
    assert psnr(a, b, mask=mask) == pytest.approx(10 * np.log10(1 / inside), abs=1e-4)
    with pytest.raises(ValueError, match="empty"):
        psnr(a, b, mask=np.zeros((40, 44)))


def test_input_errors_are_clear():
    a, b = pair((16, 16, 3))
    with pytest.raises(ValueError, match="shapes differ"):
        psnr(a, b[:8])
    with pytest.raises(TypeError, match="255"):
        ssim((a * 255).astype(np.uint8), b)
    with pytest.raises(ValueError, match="NaN"):
        psnr(a * np.nan, b)
    with pytest.raises(ValueError, match="at least 11"):
        ssim(a[:8, :8], b[:8, :8])


# --- protocols ------------------------------------------------------------------------------------


def test_registry_and_definition_round_trip():
    builtin = {"olatbench-v1", "olatbench-v1-masked", "ssdgs", "nrhints"}
    assert builtin <= set(protocol_names())
    for name in sorted(builtin):  # other tests may register their own protocols in this process
        protocol = get_protocol(name)
        definition = json.loads(json.dumps(protocol.definition()))
        assert definition["id"] == name and definition["version"] == protocol.version
        assert get_protocol(definition["id"]).definition() == definition
        assert definition["metrics"][:3] == ["psnr", "ssim", "lpips"] and definition["steps"]
    with pytest.raises(ValueError, match="known: "):
        get_protocol("nope")


def test_protocol_recipes_differ_where_they_should():
    a, b = pair((48, 40, 3), seed=5)
    v1, nr, sd = (get_protocol(n).evaluate(a, b) for n in ("olatbench-v1", "nrhints", "ssdgs"))
    qa, qb = (np.rint(x * 255) / 255 for x in (a, b))
    assert v1["psnr"] == pytest.approx(peak_signal_noise_ratio(qa, qb, data_range=1), abs=1e-6)
    assert v1["ssim"] == pytest.approx(
        skimage_ssim(qa.astype(np.float32), qb.astype(np.float32)), abs=1e-5
    )
    assert nr["psnr"] == pytest.approx(peak_signal_noise_ratio(a, b, data_range=1), abs=1e-5)
    assert nr["ssim"] == pytest.approx(skimage_ssim(a, b), abs=1e-5)
    assert sd["psnr"] == pytest.approx(v1["psnr"], abs=1e-9)
    assert sd["ssim"] == pytest.approx(
        ssim(qa.astype(np.float32), qb.astype(np.float32), variant="3dgs"), abs=1e-6
    )
    # 8-bit inputs: quantisation changes nothing, so v1 and nrhints agree on PSNR/SSIM
    v1q, nrq = (
        get_protocol("olatbench-v1").evaluate(qa, qb),
        get_protocol("nrhints").evaluate(qa, qb),
    )
    assert v1q["psnr"] == pytest.approx(nrq["psnr"], abs=1e-6) and v1q["ssim"] == pytest.approx(
        nrq["ssim"], abs=1e-6
    )


def test_protocol_clips_and_rejects_bad_input():
    a, b = pair((32, 32, 3))
    v1 = get_protocol("nrhints")
    assert v1.evaluate(a * 2 - 0.5, b)["psnr"] == pytest.approx(
        v1.evaluate(np.clip(a * 2 - 0.5, 0, 1), b)["psnr"]
    )
    with pytest.raises(ValueError, match="pred 0"):
        v1.evaluate(a[..., :2], b)
    with pytest.raises(ValueError, match="NaN"):
        v1.evaluate(a, b * np.nan)
    with pytest.raises(ValueError, match="needs a mask"):
        get_protocol("olatbench-v1-masked").evaluate(a, b)


def test_identical_images_score_finite():
    a, _ = pair((32, 32, 3))
    values = get_protocol("nrhints").evaluate(a, a)
    assert values["psnr"] == 100.0 and values["ssim"] == pytest.approx(1.0, abs=1e-6)
    json.dumps(values, allow_nan=False)


def test_evaluate_many_batches_like_singles_and_mean():
    protocol = get_protocol("olatbench-v1")
    pairs = [pair((32, 36, 3), seed=s) for s in range(3)] + [pair((40, 32, 3), seed=9)]
    many = protocol.evaluate_many(pairs, batch_size=2)
    for (a, b), row in zip(pairs, many, strict=True):
        single = protocol.evaluate(a, b)
        for key in ("psnr", "ssim"):
            assert row[key] == pytest.approx(single[key], abs=1e-6)
    mean = protocol.mean(many)
    assert mean["psnr"] == pytest.approx(np.mean([r["psnr"] for r in many]))
    assert (
        protocol.mean(
            [{"psnr": 1.0, "ssim": 0.5, "lpips": None}, {"psnr": 3.0, "ssim": 0.7, "lpips": 0.1}]
        )["lpips"]
        is None
    )


def test_missing_weights_give_none_with_one_warning(no_lpips_weights):
    protocol = get_protocol("nrhints")
    a, b = pair((24, 24, 3))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        first = protocol.evaluate(a, b)
        protocol.evaluate(a, b)
    assert first["lpips"] is None and first["psnr"] is not None
    messages = [str(w.message) for w in caught if "LPIPS" in str(w.message)]
    assert len(messages) == 1 and "olatbench weights install" in messages[0]
    assert not protocol.lpips_available()


def test_hdr_flip_fixed_exposure_range():
    from olatbench.metrics.flip import HDR_PARAMETERS, flip_available, hdr_flip

    if not flip_available():
        pytest.skip("optional package flip-evaluator is not installed")
    import flip_evaluator

    rng = np.random.default_rng(0)
    gt = (rng.random((48, 48, 3)) * 4).astype(np.float32)
    assert hdr_flip(gt, gt) == 0.0
    small, large = hdr_flip(gt * 1.2, gt), hdr_flip(gt * 2.0, gt)
    assert 0 < small < large
    _, mean, used = flip_evaluator.evaluate(
        gt, gt * 2.0, "HDR", inputsRGB=False, applyMagma=False, parameters=dict(HDR_PARAMETERS)
    )
    assert (
        used["startExposure"] == -3.0 and used["stopExposure"] == 3.0 and used["numExposures"] == 7
    )
    assert large == pytest.approx(float(mean))
    with pytest.raises(ValueError, match="non-negative"):
        hdr_flip(gt - 1, gt)
