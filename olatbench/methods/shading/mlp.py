"""A plain MLP: the network body shared by SSD-GS's SSS network and GS³'s other-effects network."""

from __future__ import annotations

from torch import nn


def mlp(
    in_dim: int, hidden: int, out_dim: int, num_linear: int, last_hidden: int | None = None
) -> nn.Sequential:
    """``num_linear`` Linear layers (ReLU between them, none after the last), every hidden layer
    ``hidden`` wide but the last, which is ``last_hidden`` wide when given (SSD-GS's official SSS
    network: 256-256-256-128)."""
    if num_linear < 2:
        raise ValueError("an MLP needs at least 2 linear layers")
    widths = [hidden] * (num_linear - 1)
    if last_hidden is not None:
        widths[-1] = last_hidden
    layers: list[nn.Module] = []
    for width_in, width_out in zip([in_dim, *widths[:-1]], widths, strict=True):
        layers += [nn.Linear(width_in, width_out), nn.ReLU()]
    layers.append(nn.Linear(widths[-1], out_dim))
    return nn.Sequential(*layers)
