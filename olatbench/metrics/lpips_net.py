"""The LPIPS network (Zhang et al. 2018, v0.1 linear heads) in plain torch, without torchvision.

Numerically the ``lpips`` package's ``LPIPS(net=..., version="0.1")`` in eval mode:

1. scaling layer ``(x - shift) / scale`` with shift (-.030, -.088, -.188), scale (.458, .448, .450),
   applied to images in **[-1, 1]**;
2. the torchvision backbone's ``features`` up to the last tap: AlexNet taps relu1…relu5
   (``features.1, 4, 7, 9, 11``), VGG16 taps relu1_2, relu2_2, relu3_3, relu4_3, relu5_3
   (``features.3, 8, 15, 22, 29``);
3. per tap: channel-normalise ``f / (sqrt(Σ_c f²) + 1e-10)``, squared difference, the 1×1 linear
   head (no bias; dropout is a no-op in eval), spatial mean; the sum over taps is the distance.

Parameters use torchvision's state-dict names (``features.<i>.weight``/``bias``) plus
``lin<k>.weight`` of shape (1, C_k, 1, 1), so a torchvision checkpoint plus the lpips heads load
directly.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

SHIFT = (-0.030, -0.088, -0.188)
SCALE = (0.458, 0.448, 0.450)
NETS: tuple[str, ...] = ("alex", "vgg")

# Per backbone: torchvision ``features`` layers as (kind, args); taps are indices of ReLU layers.
_ALEX_LAYERS = [
    ("conv", (3, 64, 11, 4, 2)),
    ("relu", ()),
    ("pool", (3, 2)),
    ("conv", (64, 192, 5, 1, 2)),
    ("relu", ()),
    ("pool", (3, 2)),
    ("conv", (192, 384, 3, 1, 1)),
    ("relu", ()),
    ("conv", (384, 256, 3, 1, 1)),
    ("relu", ()),
    ("conv", (256, 256, 3, 1, 1)),
    ("relu", ()),
]
_ALEX_TAPS = (1, 4, 7, 9, 11)


def _vgg16_layers() -> list[tuple[str, tuple[int, ...]]]:
    layers: list[tuple[str, tuple[int, ...]]] = []
    channels = 3
    for width in (
        64,
        64,
        "M",
        128,
        128,
        "M",
        256,
        256,
        256,
        "M",
        512,
        512,
        512,
        "M",
        512,
        512,
        512,
    ):
        if width == "M":
            layers.append(("pool", (2, 2)))
        else:
            layers += [("conv", (channels, width, 3, 1, 1)), ("relu", ())]
            channels = width
    return layers


_VGG_LAYERS = _vgg16_layers()
_VGG_TAPS = (3, 8, 15, 22, 29)
ARCHITECTURES = {"alex": (_ALEX_LAYERS, _ALEX_TAPS), "vgg": (_VGG_LAYERS, _VGG_TAPS)}


def tap_channels(net: str) -> tuple[int, ...]:
    """Channels of the five tapped feature maps of ``net``."""
    layers, taps = ARCHITECTURES[net]
    channels, out = 3, []
    for index, (kind, args) in enumerate(layers):
        if kind == "conv":
            channels = args[1]
        if index in taps:
            out.append(channels)
    return tuple(out)


class LPIPSNet(nn.Module):
    """LPIPS distance network; ``forward(x, y)`` takes (B, 3, H, W) images in [-1, 1] and returns
    (B,)."""

    def __init__(self, net: str = "alex") -> None:
        super().__init__()
        if net not in ARCHITECTURES:
            raise ValueError(f"unknown LPIPS backbone {net!r}; expected one of {NETS}")
        self.net = net
        layers, self.taps = ARCHITECTURES[net]
        self.layers = layers[: max(self.taps) + 1]
        self.features = nn.ModuleDict()
        for index, (kind, args) in enumerate(self.layers):
            if kind == "conv":
                c_in, c_out, kernel, stride, padding = args
                self.features[str(index)] = nn.Conv2d(
                    c_in, c_out, kernel, stride=stride, padding=padding
                )
        for k, channels in enumerate(tap_channels(net)):
            self.register_parameter(f"lin{k}", nn.Parameter(torch.zeros(1, channels, 1, 1)))
        self.register_buffer("shift", torch.tensor(SHIFT).view(1, 3, 1, 1), persistent=False)
        self.register_buffer("scale", torch.tensor(SCALE).view(1, 3, 1, 1), persistent=False)
        self.requires_grad_(False)
        self.eval()

    def load_lpips_state(self, state: dict[str, torch.Tensor]) -> LPIPSNet:
        """Load ``features.<i>.weight/bias`` + ``lin<k>.weight`` tensors (extra keys refused)."""
        own = self.state_dict()
        missing = sorted(set(own) - set(state))
        unexpected = sorted(set(state) - set(own))
        if missing or unexpected:
            raise ValueError(
                f"LPIPS-{self.net} weights do not fit: missing {missing[:4]}, unexpected "
                f"{unexpected[:4]}"
            )
        for key, value in state.items():
            if tuple(value.shape) != tuple(own[key].shape):
                raise ValueError(
                    f"LPIPS-{self.net} weight {key}: shape {tuple(value.shape)}, "
                    f"expected {tuple(own[key].shape)}"
                )
        self.load_state_dict(state)
        return self

    def tapped_features(self, x: torch.Tensor) -> list[torch.Tensor]:
        """The five channel-normalised tapped feature maps of scaled input ``x``."""
        out = []
        for index, (kind, args) in enumerate(self.layers):
            if kind == "conv":
                x = self.features[str(index)](x)
            elif kind == "relu":
                x = F.relu(x)
            else:
                x = F.max_pool2d(x, kernel_size=args[0], stride=args[1])
            if index in self.taps:
                out.append(x / (torch.sqrt(torch.sum(x * x, dim=1, keepdim=True)) + 1e-10))
        return out

    def forward(self, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        """LPIPS distance of (B, 3, H, W) images in [-1, 1] -> (B,)."""
        both = torch.cat([x, y], dim=0)
        feats = self.tapped_features((both - self.shift) / self.scale)
        batch = x.shape[0]
        total = torch.zeros(batch, dtype=x.dtype, device=x.device)
        for k, f in enumerate(feats):
            diff = (f[:batch] - f[batch:]) ** 2
            total = total + F.conv2d(diff, getattr(self, f"lin{k}")).mean(dim=(1, 2, 3))
        return total
