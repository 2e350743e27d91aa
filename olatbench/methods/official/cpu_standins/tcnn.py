"""``tinycudann.Encoding`` and ``tinycudann.Network`` in torch, for the configurations the authors'
code uses.

SSD-GS (26e4251) and GS³ (83c8daa) ``scene/neural_phase_function.py`` build::

    tcnn.Encoding(3, {"otype": "Frequency", "n_frequencies": 8})
    tcnn.Network(n_in, n_out, {"otype": "FullyFusedMLP", "activation": "LeakyReLU",
                               "output_activation": "Sigmoid", "n_neurons": 64 or 128,
                               "n_hidden_layers": 3})

What tiny-cuda-nn computes for them, reproduced here:

- Frequency encoding of x (D dims) with F frequencies: D·2F outputs; output ``j`` is ``sin(2^((j //
  2) % F) · π · x[j // 2F] + (j % 2) · π/2)``, i.e. per input dimension sin, cos of π·x, then of
  2π·x, ... (tiny-cuda-nn's ``frequency`` encoding kernel). No parameters.
- FullyFusedMLP: ``tcnn.Network`` is a network behind an Identity encoding that pads the input to a
  multiple of 16 with ones (``encodings/identity.h``: padded dims are set to 1, acting as a bias of
  the first layer); then ``n_hidden_layers`` layers of ``n_neurons`` without biases, each followed
  by the activation (LeakyReLU with slope 0.01), and an output layer of ``n_out`` padded to 16 rows,
  followed by the output activation (Sigmoid); the first ``n_out`` outputs are returned. All weights
  live in one flat parameter ``params`` (as in tiny-cuda-nn), so the module has no ``nn.Linear``
  children: the authors' ``for n, m in named_children(): if isinstance(m, nn.Linear):
  constant_(m.weight, 0)`` does nothing, as with the real module. Initialisation: each layer's
  weights uniform in ±sqrt(6 / (fan_in + fan_out)) over the padded widths
  (tiny-cuda-nn's Xavier-uniform), drawn from torch's generator rather than tiny-cuda-nn's pcg32
  (same distribution, other numbers).

Differences: everything runs in float32 (tiny-cuda-nn's FullyFusedMLP computes and returns float16).
Any other ``otype``, activation or width raises `NotImplementedError` naming the configuration.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import torch
from torch import nn

ALIGNMENT = 16  # FullyFusedMLP pads its input and output widths to multiples of 16
LEAKY_RELU_SLOPE = 0.01
FULLY_FUSED_WIDTHS = (16, 32, 64, 128)


def _unsupported(kind: str, config: Mapping[str, Any], why: str) -> NotImplementedError:
    return NotImplementedError(
        f"tinycudann stand-in (olatbench CPU): {kind} config {dict(config)} is not "
        f"implemented ({why}); it implements the authors' Frequency encoding and "
        f"FullyFusedMLP (LeakyReLU, Sigmoid output) only"
    )


def _padded(width: int) -> int:
    return -(-width // ALIGNMENT) * ALIGNMENT


def fully_fused_shapes(
    n_input_dims: int, n_output_dims: int, width: int, hidden_layers: int
) -> list[tuple[int, int]]:
    """The layer matrices' shapes [out, in] of a FullyFusedMLP, in the order of its flat
    ``params``: the input padded to a multiple of `ALIGNMENT`, ``hidden_layers`` layers of
    ``width``, the output padded to a multiple of `ALIGNMENT` rows."""
    return (
        [(width, _padded(n_input_dims))]
        + [(width, width)] * (hidden_layers - 1)
        + [(_padded(n_output_dims), width)]
    )


def layer_weights(params: torch.Tensor, shapes: list[tuple[int, int]]) -> list[torch.Tensor]:
    """The layer matrices [out, in] of ``shapes`` as views of the flat ``params``."""
    out, start = [], 0
    for rows, cols in shapes:
        out.append(params[start : start + rows * cols].view(rows, cols))
        start += rows * cols
    return out


def frequency_encoding(x: torch.Tensor, n_frequencies: int) -> torch.Tensor:
    """tiny-cuda-nn's Frequency encoding (module docstring): ``x`` [..., D] -> [..., D·2F]."""
    scales = (2.0 ** torch.arange(n_frequencies, dtype=x.dtype, device=x.device)) * math.pi  # [F]
    angles = x[..., :, None] * scales  # [..., D, F]
    # [..., D, F, 2]: sin, then cos (+π/2)
    pairs = torch.stack([torch.sin(angles), torch.cos(angles)], dim=-1)
    return pairs.reshape(*x.shape[:-1], x.shape[-1] * 2 * n_frequencies)


class Encoding(nn.Module):
    """``tinycudann.Encoding(n_input_dims, encoding_config, seed=1337, dtype=None)`` for ``otype``
    Frequency."""

    def __init__(
        self,
        n_input_dims: int,
        encoding_config: Mapping[str, Any],
        seed: int = 1337,
        dtype: torch.dtype | None = None,
    ) -> None:
        super().__init__()
        config = dict(encoding_config)
        if config.get("otype") != "Frequency" or set(config) - {"otype", "n_frequencies"}:
            raise _unsupported("encoding", config, "only otype Frequency with n_frequencies")
        self.n_input_dims = int(n_input_dims)
        self.n_frequencies = int(config.get("n_frequencies", 12))  # tiny-cuda-nn's default
        self.n_output_dims = self.n_input_dims * 2 * self.n_frequencies
        self.seed, self.dtype = seed, torch.float32 if dtype is None else dtype
        self.params = nn.Parameter(torch.zeros(0))  # the Frequency encoding has no parameters

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.shape[-1] != self.n_input_dims:
            raise ValueError(
                f"tinycudann stand-in Encoding: expected [..., {self.n_input_dims}], got "
                f"{tuple(x.shape)}"
            )
        return frequency_encoding(x.float(), self.n_frequencies)


class Network(nn.Module):
    """``tinycudann.Network(n_input_dims, n_output_dims, network_config, seed=1337)`` for
    FullyFusedMLP."""

    def __init__(
        self,
        n_input_dims: int,
        n_output_dims: int,
        network_config: Mapping[str, Any],
        seed: int = 1337,
    ) -> None:
        super().__init__()
        config = dict(network_config)
        known = {"otype", "activation", "output_activation", "n_neurons", "n_hidden_layers"}
        if (
            config.get("otype") != "FullyFusedMLP"
            or config.get("activation") != "LeakyReLU"
            or config.get("output_activation") != "Sigmoid"
            or set(config) - known
        ):
            raise _unsupported(
                "network",
                config,
                "otype must be FullyFusedMLP with activation LeakyReLU and "
                "output_activation Sigmoid",
            )
        width, hidden = int(config.get("n_neurons", 128)), int(config.get("n_hidden_layers", 5))
        if width not in FULLY_FUSED_WIDTHS or hidden < 1:
            raise _unsupported(
                "network",
                config,
                f"n_neurons must be one of {FULLY_FUSED_WIDTHS} and n_hidden_layers at least 1",
            )
        self.n_input_dims, self.n_output_dims, self.seed = (
            int(n_input_dims),
            int(n_output_dims),
            seed,
        )
        self.shapes = fully_fused_shapes(self.n_input_dims, self.n_output_dims, width, hidden)
        generator = torch.Generator().manual_seed(seed)
        chunks = [
            (torch.rand(rows * cols, generator=generator) * 2 - 1) * math.sqrt(6.0 / (rows + cols))
            for rows, cols in self.shapes
        ]
        self.params = nn.Parameter(torch.cat(chunks))

    def weights(self) -> list[torch.Tensor]:
        """The layer matrices [out, in] as views of ``params``."""
        return layer_weights(self.params, self.shapes)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.shape[-1] != self.n_input_dims:
            raise ValueError(
                f"tinycudann stand-in Network: expected [..., {self.n_input_dims}], got "
                f"{tuple(x.shape)}"
            )
        pad = self.shapes[0][1] - self.n_input_dims
        h = torch.cat([x.float(), x.new_ones(*x.shape[:-1], pad, dtype=torch.float32)], dim=-1)
        layers = self.weights()
        for weight in layers[:-1]:
            h = torch.nn.functional.leaky_relu(h @ weight.T, LEAKY_RELU_SLOPE)
        return torch.sigmoid(h @ layers[-1].T)[..., : self.n_output_dims]
