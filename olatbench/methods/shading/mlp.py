"""A plain MLP: the network body shared by SSD-GS's SSS network and GS³'s other-effects network."""

from __future__ import annotations

from torch import nn


def mlp(in_dim: int, hidden: int, out_dim: int, num_linear: int) -> nn.Sequential:
    """``num_linear`` Linear layers (ReLU between them, none after the last)."""
    if num_linear < 2:
        raise ValueError("an MLP needs at least 2 linear layers")
    layers: list[nn.Module] = [nn.Linear(in_dim, hidden), nn.ReLU()]
    for _ in range(num_linear - 2):
        layers += [nn.Linear(hidden, hidden), nn.ReLU()]
    layers.append(nn.Linear(hidden, out_dim))
    return nn.Sequential(*layers)
