"""Turn user images (numpy or torch, channel-last) into the (B, C, H, W) float tensors the metrics
use."""

from __future__ import annotations

import numpy as np
import torch

ArrayLike = np.ndarray | torch.Tensor


def to_nchw(
    x: ArrayLike,
    name: str = "image",
    dtype: torch.dtype | None = None,
    device: torch.device | str | None = None,
) -> tuple[torch.Tensor, bool]:
    """(H, W, C) or (B, H, W, C) numpy/torch -> ((B, C, H, W) float tensor, was_batched).

    Torch inputs keep their autograd graph and device (unless ``device`` is given); numpy inputs
    become float32 tensors (float64 stays float64). Non-finite values raise ``ValueError``.
    """
    tensor = torch.from_numpy(np.ascontiguousarray(x)) if isinstance(x, np.ndarray) else x
    if not isinstance(tensor, torch.Tensor):
        raise TypeError(f"{name}: expected a numpy array or torch tensor, found {type(x).__name__}")
    if tensor.ndim not in (3, 4):
        raise ValueError(
            f"{name}: expected (H, W, C) or (B, H, W, C), found shape {tuple(tensor.shape)}"
        )
    batched = tensor.ndim == 4
    if not tensor.is_floating_point():
        raise TypeError(
            f"{name}: expected float values in [0, 1], found dtype {tensor.dtype} "
            "(divide 8-bit images by 255 first)"
        )
    if dtype is None:
        dtype = torch.float64 if tensor.dtype == torch.float64 else torch.float32
    tensor = tensor.to(dtype=dtype, device=device)
    if not batched:
        tensor = tensor.unsqueeze(0)
    if not bool(torch.isfinite(tensor.detach()).all()):
        raise ValueError(f"{name}: contains NaN or Inf values")
    return tensor.permute(0, 3, 1, 2), batched


def mask_to_n1hw(
    mask: ArrayLike | None, like: torch.Tensor, name: str = "mask"
) -> torch.Tensor | None:
    """(H, W), (H, W, 1), (B, H, W) or (B, H, W, 1) mask in [0, 1] -> (B, 1, H, W) tensor like
    ``like``."""
    if mask is None:
        return None
    m = torch.from_numpy(np.ascontiguousarray(mask)) if isinstance(mask, np.ndarray) else mask
    m = m.to(dtype=like.dtype, device=like.device)
    if m.ndim >= 3 and m.shape[-1] == 1:
        m = m[..., 0]
    if m.ndim == 2:
        m = m.unsqueeze(0)
    if m.ndim != 3 or tuple(m.shape[-2:]) != tuple(like.shape[-2:]):
        raise ValueError(
            f"{name}: shape {tuple(m.shape)} does not match the images' (H, W) = "
            f"{tuple(like.shape[-2:])}"
        )
    m = m.unsqueeze(1).expand(like.shape[0], 1, *like.shape[-2:])
    if float(m.sum()) <= 0:
        raise ValueError(f"{name}: is empty (no pixel inside the mask)")
    return m


def check_same_shape(pred: torch.Tensor, gt: torch.Tensor) -> None:
    """Raise ``ValueError`` unless pred and gt have the same (B, C, H, W) shape."""
    if pred.shape != gt.shape:
        raise ValueError(
            f"pred and gt shapes differ: {tuple(pred.permute(0, 2, 3, 1).shape)} vs "
            f"{tuple(gt.permute(0, 2, 3, 1).shape)} (B, H, W, C)"
        )


def check_unit_range(x: torch.Tensor, name: str, tolerance: float = 1e-6) -> None:
    """Range guard: refuse values outside [0, 1] (the metrics' input convention)."""
    low, high = float(x.detach().min()), float(x.detach().max())
    if low < -tolerance or high > 1 + tolerance:
        raise ValueError(
            f"{name}: values must lie in [0, 1] (found [{low:.4g}, {high:.4g}]); clip or convert "
            "the images first (a [-1, 1] image is not accepted here)"
        )


def to_output(values: torch.Tensor, batched: bool) -> float | np.ndarray:
    """(B,) tensor -> float for a single image, numpy (B,) for a batch."""
    values = values.detach().cpu().double()
    return values.numpy() if batched else float(values[0])
