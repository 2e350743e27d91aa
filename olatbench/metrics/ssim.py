"""SSIM (Wang et al. 2004) with an 11-tap Gaussian window (σ = 1.5), in vectorised torch.

Two variants, both with K1 = 0.01, K2 = 0.03, data range 1 and population (biased) covariances:

- ``"wang"``: the mean of the SSIM map over the *valid* region only (pixels whose whole window lies
  inside the image), averaged over channels. Equal to scikit-image's
  ``structural_similarity(gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
  data_range=1, channel_axis=-1)`` and to torchmetrics ≥ 1.0
  ``structural_similarity_index_measure(data_range=1.0)`` (reflect padding followed by cropping the
  padded border is the valid region).
- ``"3dgs"``: the ``ssim`` of 3D Gaussian Splatting's ``utils/loss_utils.py`` (used by SSD-GS): the
  same window applied with *zero padding* of 5 pixels, mean over the full map (borders included).

``ssim_torch`` is differentiable and accepts channel-first or channel-last tensors; ``ssim_loss`` is
the ``1 - SSIM`` training loss of 3DGS-style methods. ``ssim_loss(backend="auto")`` (the default)
computes the ``"3dgs"`` variant with the C++ kernel of ``ssim_cpu`` (hand-written backward, several
times faster) when the images are CPU float32/float64 tensors of one dtype, at least 11×11, and
``gt`` does not require grad; any other call uses the torch code here. See ``resolve_ssim_backend``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np
import torch
import torch.nn.functional as F

from olatbench._native import Unavailable, always, choose_backend
from olatbench.metrics._inputs import ArrayLike, check_same_shape, mask_to_n1hw, to_nchw, to_output
from olatbench.metrics.ssim_cpu import LIBRARY, ssim_loss_cpu, unsupported_reason

if TYPE_CHECKING:
    from olatbench.metrics.protocols import Protocol
    from olatbench.metrics.registry import MetricBatch

SSIMVariant = Literal["wang", "3dgs"]
SSIM_VARIANTS: tuple[str, ...] = ("wang", "3dgs")
SSIMBackend = Literal["auto", "torch", "cpu"]
# overrides backend="auto" (e.g. "torch": the path CUDA tensors take, on the CPU)
SSIM_ENV = "OLATBENCH_SSIM"
WINDOW_SIZE = 11
SIGMA = 1.5
K1, K2 = 0.01, 0.03


def gaussian_taps(
    size: int = WINDOW_SIZE,
    sigma: float = SIGMA,
    dtype: torch.dtype = torch.float32,
    device: torch.device | str | None = None,
) -> torch.Tensor:
    """Normalised 1D Gaussian (size,) centred on the middle tap: ``exp(-(i - size//2)² / 2σ²)``."""
    # float64 taps, then moved
    offsets = torch.arange(size, dtype=torch.float64, device="cpu") - size // 2
    taps = torch.exp(-(offsets**2) / (2 * sigma**2))
    # a GPU queues the upload
    return (taps / taps.sum()).to(dtype=dtype).to(device, non_blocking=True)


def _blur(stack: torch.Tensor, taps: torch.Tensor, padding: int) -> torch.Tensor:
    """Separable Gaussian blur of every channel of (B, K, H, W); zero padding of ``padding``
    pixels."""
    channels = stack.shape[1]
    horizontal = taps.view(1, 1, 1, -1).expand(channels, 1, 1, taps.numel())
    vertical = taps.view(1, 1, -1, 1).expand(channels, 1, taps.numel(), 1)
    out = F.conv2d(stack, horizontal, padding=(0, padding), groups=channels)
    return F.conv2d(out, vertical, padding=(padding, 0), groups=channels)


def ssim_map_torch(
    pred: torch.Tensor, gt: torch.Tensor, variant: SSIMVariant = "wang", data_range: float = 1.0
) -> torch.Tensor:
    """SSIM map of (B, C, H, W) tensors: (B, C, H-10, W-10) for ``wang`` (valid), (B, C, H, W) for
    ``3dgs``."""
    _check_variant(variant)
    if min(pred.shape[-2:]) < WINDOW_SIZE:
        raise ValueError(
            f"SSIM needs images of at least {WINDOW_SIZE}×{WINDOW_SIZE} pixels, found "
            f"{tuple(pred.shape[-2:])}"
        )
    channels = pred.shape[1]
    taps = gaussian_taps(dtype=pred.dtype, device=pred.device)
    stack = torch.cat([pred, gt, pred * pred, gt * gt, pred * gt], dim=1)
    blurred = _blur(stack, taps, padding=WINDOW_SIZE // 2 if variant == "3dgs" else 0)
    mu_p, mu_g, e_pp, e_gg, e_pg = blurred.split(channels, dim=1)
    var_p, var_g, cov = e_pp - mu_p * mu_p, e_gg - mu_g * mu_g, e_pg - mu_p * mu_g
    c1, c2 = (K1 * data_range) ** 2, (K2 * data_range) ** 2
    numerator = (2 * mu_p * mu_g + c1) * (2 * cov + c2)
    denominator = (mu_p * mu_p + mu_g * mu_g + c1) * (var_p + var_g + c2)
    return numerator / denominator


def _valid_mask(mask: torch.Tensor, variant: SSIMVariant) -> torch.Tensor:
    """Crop a (B, 1, H, W) mask to the SSIM map's region."""
    if variant == "3dgs":
        return mask
    half = WINDOW_SIZE // 2
    return mask[..., half:-half, half:-half]


def ssim_nchw(
    pred: torch.Tensor,
    gt: torch.Tensor,
    variant: SSIMVariant = "wang",
    mask: torch.Tensor | None = None,
) -> torch.Tensor:
    """Per-image SSIM of (B, C, H, W) tensors -> (B,); ``mask`` (B, 1, H, W) weights the map's
    pixels."""
    ssim_map = ssim_map_torch(pred, gt, variant)
    if mask is None:
        return ssim_map.flatten(1).mean(1)
    m = _valid_mask(mask, variant)
    weight = m.flatten(1).sum(1) * ssim_map.shape[1]
    if bool((weight <= 0).any()):
        raise ValueError("mask: no masked pixel lies inside the SSIM valid region")
    return (ssim_map * m).flatten(1).sum(1) / weight


def _check_variant(variant: str) -> None:
    if variant not in SSIM_VARIANTS:
        raise ValueError(f"unknown SSIM variant {variant!r}; expected one of {SSIM_VARIANTS}")


def _batched_nchw(
    pred: torch.Tensor, gt: torch.Tensor, channels_last: bool
) -> tuple[torch.Tensor, torch.Tensor]:
    """(C, H, W) / (B, C, H, W), or channel-last with ``channels_last=True`` -> (B, C, H, W)
    views."""
    if channels_last:
        pred, gt = pred.movedim(-1, -3), gt.movedim(-1, -3)
    if pred.ndim == 3:
        pred, gt = pred.unsqueeze(0), gt.unsqueeze(0)
    check_same_shape(pred, gt)
    return pred, gt


def ssim_torch(
    pred: torch.Tensor,
    gt: torch.Tensor,
    variant: SSIMVariant = "3dgs",
    channels_last: bool = False,
    mask: torch.Tensor | None = None,
) -> torch.Tensor:
    """Differentiable SSIM of torch images -> (B,) (or a 0-dim tensor for an unbatched input).

    Layout: (C, H, W) / (B, C, H, W), or (H, W, C) / (B, H, W, C) with ``channels_last=True``.
    Default variant ``3dgs`` (zero padding) as used in 3DGS-style training losses.
    """
    batched = pred.ndim == 4
    values = ssim_nchw(*_batched_nchw(pred, gt, channels_last), variant, mask)
    return values if batched else values[0]


def resolve_ssim_backend(
    pred: torch.Tensor,
    gt: torch.Tensor,
    variant: SSIMVariant = "3dgs",
    backend: SSIMBackend = "auto",
) -> Literal["torch", "cpu"]:
    """The backend ``ssim_loss`` uses for (B, C, H, W) ``pred``/``gt``: ``"torch"`` or ``"cpu"``
    (C++ kernel).

    ``"cpu"`` handles the ``"3dgs"`` variant of CPU float32/float64 tensors of one dtype, at least
    11×11, whose ``gt`` does not require grad. ``backend="auto"`` picks it for such inputs when the
    C++ library builds and otherwise ``"torch"``; a failed build falls back to torch with one
    RuntimeWarning saying why (``olatbench._native.choose_backend``). ``backend="cpu"`` raises
    ValueError for other inputs and RuntimeError when the library cannot be built; ``"torch"``
    always uses the torch code. The environment variable ``OLATBENCH_SSIM``
    (``auto``, ``torch`` or ``cpu``) overrides ``"auto"``."""
    _check_variant(variant)

    def cpu_check() -> Unavailable | None:
        if variant != "3dgs":
            reason = f"it implements only the '3dgs' variant, not {variant!r}"
        elif min(pred.shape[-2:]) < WINDOW_SIZE:
            reason = (
                f"it needs images of at least {WINDOW_SIZE}×{WINDOW_SIZE} pixels, found "
                f"{tuple(pred.shape[-2:])}"
            )
        else:
            reason = unsupported_reason(pred, gt)
        return Unavailable(reason) if reason is not None else LIBRARY.unavailable()

    return choose_backend(
        backend,
        pred.device.type,
        {"cpu": cpu_check, "torch": always},
        kind="SSIM",
        env_var=SSIM_ENV,
    )


def ssim_loss(
    pred: torch.Tensor,
    gt: torch.Tensor,
    variant: SSIMVariant = "3dgs",
    channels_last: bool = False,
    backend: SSIMBackend = "auto",
) -> torch.Tensor:
    """``1 - SSIM`` averaged over the batch: a differentiable 0-dim training loss
    (3DGS D-SSIM term).

    Layout as ``ssim_torch``; ``backend`` as ``resolve_ssim_backend`` (the C++ kernel differentiates
    ``pred`` only, so a ``gt`` that requires grad goes to torch under "auto"). The backends agree up
    to rounding."""
    pred, gt = _batched_nchw(pred, gt, channels_last)
    if resolve_ssim_backend(pred, gt, variant, backend) == "cpu":
        return ssim_loss_cpu(pred, gt)
    return 1.0 - ssim_nchw(pred, gt, variant).mean()


def ssim(
    pred: ArrayLike, gt: ArrayLike, variant: SSIMVariant = "wang", mask: ArrayLike | None = None
) -> float | np.ndarray:
    """SSIM of channel-last images (H, W, C) / (B, H, W, C) in [0, 1] (numpy or torch), no gradient.

    Returns a float for one image, a (B,) array for a batch. ``mask`` (H, W) weights the SSIM map.
    """
    p, batched = to_nchw(pred, "pred")
    g, _ = to_nchw(gt, "gt", dtype=p.dtype, device=p.device)
    check_same_shape(p, g)
    with torch.no_grad():
        return to_output(ssim_nchw(p, g, variant, mask_to_n1hw(mask, p)), batched)


def protocol_ssim(batch: MetricBatch, protocol: Protocol) -> list[float]:
    """The ``ssim`` metric: `ssim_nchw` of the protocol's ``ssim_variant`` per image (mask-weighted
    for masked protocols)."""
    return ssim_nchw(batch.pred, batch.gt, protocol.ssim_variant, batch.mask).tolist()
