"""Input encodings of the shading networks (SSD-GS's SSS and shadow networks, GS³'s networks).

* `positional_encoding`: the NeRF encoding used by the official SSS MLP,
  ``[x, sin(2^k x), cos(2^k x)]`` for ``k = 0 … L-1`` (identity included), so a 3-vector with
  ``L = 4`` becomes 27 values.
* `frequency_encoding`: the tiny-cuda-nn ``"Frequency"`` encoding used by the official shadow
  network, ``[sin(2^k π x), cos(2^k π x)]`` for ``k = 0 … L-1`` (no identity), 3 · 2L values.
"""

from __future__ import annotations

import math

import torch


def positional_encoding(x: torch.Tensor, num_freqs: int) -> torch.Tensor:
    """(…, D) -> (…, D · (1 + 2 · num_freqs)): the input, then all sines, then all cosines."""
    freqs = 2.0 ** torch.arange(num_freqs, dtype=x.dtype, device=x.device)
    scaled = (x[..., None, :] * freqs[:, None]).flatten(-2)  # (…, L·D), frequency-major
    return torch.cat([x, torch.sin(scaled), torch.cos(scaled)], dim=-1)


def positional_encoding_dim(dim: int, num_freqs: int) -> int:
    """Width of `positional_encoding` for a ``dim``-vector."""
    return dim * (1 + 2 * num_freqs)


def frequency_encoding(x: torch.Tensor, num_freqs: int) -> torch.Tensor:
    """(…, D) -> (…, D · 2 · num_freqs): ``sin(2^k π x)`` then ``cos(2^k π x)``, no identity
    term."""
    freqs = math.pi * 2.0 ** torch.arange(num_freqs, dtype=x.dtype, device=x.device)
    scaled = (x[..., None, :] * freqs[:, None]).flatten(-2)
    return torch.cat([torch.sin(scaled), torch.cos(scaled)], dim=-1)


def frequency_encoding_dim(dim: int, num_freqs: int) -> int:
    """Width of `frequency_encoding` for a ``dim``-vector."""
    return dim * 2 * num_freqs
