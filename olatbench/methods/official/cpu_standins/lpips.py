"""``lpips.LPIPS(net="alex")`` as NRHints (291800d) calls it, backed by olatbench's LPIPS, without
torchvision.

NRHints' ``utils/metrics.py`` does ``from lpips import LPIPS`` at import time and scores each test
view with ``LPIPS(net='alex', verbose=False).cpu()(rgb, rgb_gt, normalize=True).item()`` on
[1, 3, H, W] tensors in [0, 1] (lines 4 and 18-24). The ``lpips`` package imports
``torchvision.models``, which PyPI's torchvision cannot provide beside the local CPU torch
(``operator torchvision::nms does not exist``), and its ``LPIPS(net='alex')`` downloads
torchvision's AlexNet weights from a model hub at run time. This stand-in computes the same distance
with olatbench's `LPIPSNet` and the weights ``olatbench weights install`` put in place
(`olatbench.metrics.lpips.get_network`; ``WeightsError`` with the install hint when there are none),
no download.

Convention (lpips 0.1.4's ``LPIPS.forward``): inputs NCHW, RGB; ``normalize=True`` maps [0, 1] to
[-1, 1] by ``2x - 1`` before the network; no range guard (olatbench's `lpips_nchw` refuses values
outside [0, 1], the ``lpips`` package does not, and a NeuS blend may exceed 1 by a rounding error);
returns [N, 1, 1, 1]. Anything else NRHints does not use (another backbone, ``normalize=False``,
``spatial``, ``retPerLayer``, random or tuned backbones, a ``model_path``, version 0.0, the
non-learned baseline) raises `NotImplementedError` naming it.
"""

from __future__ import annotations

import torch
from torch import nn

from olatbench.metrics.lpips import get_network

_NAME = "lpips stand-in (olatbench CPU, nrhints-official)"
# __init__ arguments of lpips 0.1.4's LPIPS and the only value this stand-in accepts for each.
_FIXED = {
    "pretrained": True,
    "net": "alex",
    "version": "0.1",
    "lpips": True,
    "spatial": False,
    "pnet_rand": False,
    "pnet_tune": False,
    "model_path": None,
    "eval_mode": True,
}


class LPIPS(nn.Module):
    """lpips 0.1.4's ``LPIPS`` restricted to pretrained LPIPS-Alex v0.1 in eval mode
    (module docstring)."""

    def __init__(
        self,
        pretrained: bool = True,
        net: str = "alex",
        version: str = "0.1",
        lpips: bool = True,
        spatial: bool = False,
        pnet_rand: bool = False,
        pnet_tune: bool = False,
        use_dropout: bool = True,
        model_path: str | None = None,
        eval_mode: bool = True,
        verbose: bool = True,
    ) -> None:
        super().__init__()
        given = {
            "pretrained": pretrained,
            "net": net,
            "version": version,
            "lpips": lpips,
            "spatial": spatial,
            "pnet_rand": pnet_rand,
            "pnet_tune": pnet_tune,
            "model_path": model_path,
            "eval_mode": eval_mode,
        }
        other = {key: value for key, value in given.items() if value != _FIXED[key]}
        if other:
            raise NotImplementedError(
                f"{_NAME}: LPIPS({', '.join(f'{k}={v!r}' for k, v in other.items())}) is not "
                "implemented, only LPIPS(net='alex') with the pretrained v0.1 weights (what "
                "NRHints' utils/metrics.py uses)"
            )
        self.net_name = net  # use_dropout and verbose change nothing in eval mode / in the value

    def forward(
        self,
        in0: torch.Tensor,
        in1: torch.Tensor,
        retPerLayer: bool = False,
        normalize: bool = False,
    ) -> torch.Tensor:
        """LPIPS-Alex distance of ``in0``, ``in1`` [N, 3, H, W] in [0, 1] (``normalize=True``) ->
        [N, 1, 1, 1]."""
        if retPerLayer:
            raise NotImplementedError(f"{_NAME}: forward(..., retPerLayer=True) is not implemented")
        if not normalize:
            raise NotImplementedError(
                f"{_NAME}: forward(..., normalize=False) (inputs already in [-1, 1]) is not "
                "implemented, only normalize=True on [0, 1] images (NRHints' call)"
            )
        for name, tensor in (("in0", in0), ("in1", in1)):
            if tensor.dim() != 4 or tensor.shape[1] != 3:
                raise ValueError(
                    f"{_NAME}: {name} must be [N, 3, H, W] (NCHW, RGB), got {tuple(tensor.shape)}"
                )
        if in0.shape != in1.shape:
            raise ValueError(
                f"{_NAME}: in0 {tuple(in0.shape)} and in1 {tuple(in1.shape)} differ in shape"
            )
        network = get_network(self.net_name)
        parameter = next(network.parameters())

        def prepare(images: torch.Tensor) -> torch.Tensor:
            mapped = 2 * images - 1  # normalize=True: [0, 1] -> [-1, 1], as lpips' forward
            return mapped.to(parameter.device, parameter.dtype).contiguous(
                memory_format=torch.channels_last
            )

        return network(prepare(in0), prepare(in1)).to(in0.device).reshape(-1, 1, 1, 1)

    def extra_repr(self) -> str:
        return f"net={self.net_name!r} (olatbench LPIPSNet)"


__all__ = ["LPIPS"]
