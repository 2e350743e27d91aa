"""``torchmetrics.functional.image``'s PSNR, SSIM and LPIPS as RNG's ``render.py`` calls them,
without torchvision.

RNG's ``render.py:29`` imports ``peak_signal_noise_ratio``, ``structural_similarity_index_measure``
and ``learned_perceptual_image_patch_similarity`` from ``torchmetrics.functional.image`` and, after
rendering a split, writes their values on the stacked renders and ground truths ([N, 3, H, W] in [0,
1], default arguments) to ``metrics.txt`` (``render.py:110-119``); olatbench scores the renders
itself and does not read that file. The real package cannot be imported in a ``device=cpu`` job:
``torchmetrics.functional.image`` imports ``torchvision``'s ``transforms`` and ``models`` at import
time (its ``arniqa.py``), which the torchvision stand-in does not provide, and its LPIPS downloads
torchvision's AlexNet weights. These are the same functions at the defaults render.py uses
(torchmetrics 1.x):

- PSNR: ``10 log10(R² / mean((preds - target)²))`` over all elements,
  ``R = target.max() - target.min()``;
- SSIM: 11×11 Gaussian window (σ = 1.5), inputs reflect-padded by 5, the SSIM map cropped by 5 on
  each side and averaged per image, then over the batch; ``R = max(range(preds), range(target))``,
  ``C1 = (0.01 R)²``, ``C2 = (0.03 R)²``;
- LPIPS: AlexNet v0.1 with ``normalize=False`` (the inputs are taken as already in [-1, 1]; as
  torchmetrics 1.4.0's ``_valid_img`` (``functional/image/lpips.py:377-380``), values below -1 raise
  ValueError and values above 1 do not: RNG's colour MLP has no output activation), mean over the
  batch; olatbench's `LPIPSNet` with the weights ``olatbench weights install`` put in place
  (`olatbench.metrics.lpips.get_network`), no download.

Other arguments raise `NotImplementedError` naming them.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from olatbench.metrics.lpips import get_network

_NAME = "torchmetrics stand-in (olatbench CPU, rng-official)"


def _only_defaults(function: str, **given: object) -> None:
    other = {key: value for key, value in given.items() if value is not None}
    if other:
        raise NotImplementedError(
            f"{_NAME}: {function}({', '.join(f'{k}={v!r}' for k, v in other.items())}) is not "
            "implemented, only the defaults (RNG's render.py:113-115)"
        )


def _check(preds: torch.Tensor, target: torch.Tensor) -> None:
    if preds.shape != target.shape or preds.dim() != 4:
        raise ValueError(
            f"{_NAME}: preds and target must be [N, C, H, W] of one shape, got "
            f"{tuple(preds.shape)} and {tuple(target.shape)}"
        )


def peak_signal_noise_ratio(
    preds: torch.Tensor,
    target: torch.Tensor,
    data_range: float | None = None,
    base: float | None = None,
    reduction: str | None = None,
    dim: object = None,
) -> torch.Tensor:
    """PSNR over every element of the batch (module docstring)."""
    _only_defaults(
        "peak_signal_noise_ratio", data_range=data_range, base=base, reduction=reduction, dim=dim
    )
    value_range = (target.max() - target.min()).double()
    mse = ((preds.double() - target.double()) ** 2).mean()
    return (10.0 * torch.log10(value_range**2 / mse)).to(preds.dtype)


def _gaussian_window(size: int = 11, sigma: float = 1.5) -> torch.Tensor:
    x = torch.arange(size, dtype=torch.float64) - (size - 1) / 2
    g = torch.exp(-(x**2) / (2 * sigma**2))
    g = g / g.sum()
    return g[:, None] * g[None, :]


def structural_similarity_index_measure(
    preds: torch.Tensor,
    target: torch.Tensor,
    gaussian_kernel: bool | None = None,
    sigma: float | None = None,
    kernel_size: int | None = None,
    reduction: str | None = None,
    data_range: float | None = None,
    k1: float | None = None,
    k2: float | None = None,
) -> torch.Tensor:
    """Mean SSIM (module docstring)."""
    _only_defaults(
        "structural_similarity_index_measure",
        gaussian_kernel=gaussian_kernel,
        sigma=sigma,
        kernel_size=kernel_size,
        reduction=reduction,
        data_range=data_range,
        k1=k1,
        k2=k2,
    )
    _check(preds, target)
    p, t = preds.double(), target.double()
    value_range = torch.maximum(p.max() - p.min(), t.max() - t.min())
    c1, c2 = (0.01 * value_range) ** 2, (0.03 * value_range) ** 2
    channels, pad = p.shape[1], 5
    window = _gaussian_window()[None, None].expand(channels, 1, -1, -1)
    p, t = (F.pad(x, (pad, pad, pad, pad), mode="reflect") for x in (p, t))
    mu_p, mu_t, e_pp, e_tt, e_pt = (
        F.conv2d(x, window, groups=channels) for x in (p, t, p * p, t * t, p * t)
    )
    var_p, var_t, cov = e_pp - mu_p**2, e_tt - mu_t**2, e_pt - mu_p * mu_t
    ssim = ((2 * mu_p * mu_t + c1) * (2 * cov + c2)) / (
        (mu_p**2 + mu_t**2 + c1) * (var_p + var_t + c2)
    )
    ssim = ssim[..., pad:-pad, pad:-pad]
    return ssim.reshape(ssim.shape[0], -1).mean(-1).mean().to(preds.dtype)


def learned_perceptual_image_patch_similarity(
    img1: torch.Tensor,
    img2: torch.Tensor,
    net_type: str = "alex",
    reduction: str = "mean",
    normalize: bool = False,
) -> torch.Tensor:
    """Mean LPIPS-Alex of [N, 3, H, W] images taken as in [-1, 1] (module docstring)."""
    if (net_type, reduction, normalize) != ("alex", "mean", False):
        raise NotImplementedError(
            f"{_NAME}: learned_perceptual_image_patch_similarity(net_type={net_type!r}, "
            f"reduction={reduction!r}, normalize={normalize!r}) is not implemented, only the "
            "defaults (RNG's render.py:115)"
        )
    _check(img1, img2)
    for name, image in (("img1", img1), ("img2", img2)):
        if image.shape[1] != 3 or not image.min() >= -1:
            raise ValueError(
                f"{_NAME}: {name} must be [N, 3, H, W] with values from -1 (normalize=False), "
                f"got {tuple(image.shape)} with minimum {float(image.min()):g}"
            )
    network = get_network("alex")
    parameter = next(network.parameters())
    with torch.no_grad():
        values = network(
            *(
                x.to(parameter.device, parameter.dtype).contiguous(
                    memory_format=torch.channels_last
                )
                for x in (img1, img2)
            )
        )
    return values.reshape(-1).mean().to(img1.dtype)


__all__ = [
    "learned_perceptual_image_patch_similarity",
    "peak_signal_noise_ratio",
    "structural_similarity_index_measure",
]
