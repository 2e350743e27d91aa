"""SSD-GS per-Gaussian shading benchmark: the fused C++ kernels (``backend="cpu"``) vs the torch
ops, in one process.

Times `Shader.forward` on K float32 Gaussians with every term on (specular, SSS, shadow; the default
config: 8 ASG lobes, smooth cosine, min-scale frames oriented to the camera) and the two networks
Θ_SSS and Θ_shad replaced by `bench_ssdgs.FreeNetwork` (a constant that keeps the autograd graph),
so that only the shading itself is measured. "fwd" is the forward with its autograd graph recorded
(positions, quaternions, raw attributes and the shader's parameters require grad), "fwd+bwd" adds
``colour.sum().backward()``. Each timing is the fastest of ``--repeats`` runs after a warm-up (which
also builds the C++ library on first use), the backends alternating run by run. Also checks that
both backends give the same colour and gradients. Target: fwd+bwd ≥ 4× faster than torch at every K.
Ends with one ``SUMMARY bench_shading key=value ...`` line.

Usage: ``python benchmarks/bench_shading.py [--counts 5000 20000] [--threads 2] [--repeats 30]``
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

import torch
from backend_speedup import BACKENDS, SpeedupTable
from bench_ssdgs import FreeNetwork

from olatbench.methods.ssdgs.config import SSDGSConfig
from olatbench.methods.ssdgs.shader import Shader

TERMS = frozenset({"specular", "sss", "shadow"})
TARGET = 4.0


class Scene:
    """K Gaussians in the unit ball (log-uniform scales, random rotations and raw attributes), the
    camera at (0, -3, 1), a light at (2, -3, 3) of intensity 16, random coarse visibilities."""

    def __init__(self, count: int, seed: int = 0) -> None:
        g = torch.Generator().manual_seed(seed)
        direction = torch.nn.functional.normalize(torch.randn(count, 3, generator=g), dim=-1)
        self.positions = direction * torch.rand(count, 1, generator=g) ** (1 / 3)
        self.quats = torch.randn(count, 4, generator=g)
        self.scales = torch.exp(
            torch.empty(count, 3).uniform_(math.log(0.005), math.log(0.05), generator=g)
        )
        dims = {"diffuse": 3, "specular": 3, "sss": 3, "asg_weights": 8, "material": 6}
        self.attributes = {name: torch.randn(count, d, generator=g) for name, d in dims.items()}
        self.camera = torch.tensor([0.0, -3.0, 1.0])
        self.light = torch.tensor([2.0, -3.0, 3.0])
        self.intensity = torch.full((3,), 16.0)
        self.coarse = torch.rand(count, generator=g)

    def leaves(self) -> tuple[torch.Tensor, torch.Tensor, dict[str, torch.Tensor]]:
        """Fresh leaves requiring grad: positions, quaternions and the raw attributes."""
        return (
            self.positions.clone().requires_grad_(True),
            self.quats.clone().requires_grad_(True),
            {name: value.clone().requires_grad_(True) for name, value in self.attributes.items()},
        )


def make_shader() -> Shader:
    shader = Shader(SSDGSConfig())
    shader.sss_net, shader.shadow_net = FreeNetwork(), FreeNetwork()
    return shader


def step(shader: Shader, scene: Scene, backend: str, backward: bool) -> Callable[[], None]:
    """One shading of the scene (and backward of the colour sum) on fresh leaves."""

    def run() -> None:
        shader.backend = backend
        positions, quats, attributes = scene.leaves()
        out = shader(
            positions,
            quats,
            scene.scales,
            attributes,
            scene.camera,
            scene.light,
            scene.intensity,
            TERMS,
            scene.coarse,
        )
        if backward:
            out.colour.sum().backward()

    return run


def max_differences(shader: Shader, scene: Scene) -> tuple[float, float]:
    """Max |Δ colour| / max |colour| and the largest max |Δ grad| / max |grad| over the leaves and
    the shader's parameters, between the backends."""
    out = {}
    for backend in BACKENDS:
        shader.backend = backend
        shader.zero_grad(set_to_none=True)
        positions, quats, attributes = scene.leaves()
        colour = shader(
            positions,
            quats,
            scene.scales,
            attributes,
            scene.camera,
            scene.light,
            scene.intensity,
            TERMS,
            scene.coarse,
        ).colour
        colour.sum().backward()
        grads = [
            positions.grad,
            quats.grad,
            *(a.grad for a in attributes.values() if a.grad is not None),
            *(p.grad for p in shader.parameters() if p.grad is not None),
        ]
        out[backend] = (colour.detach(), grads)
    (colour_t, grads_t), (colour_c, grads_c) = out["torch"], out["cpu"]
    d_colour = float((colour_t - colour_c).abs().max() / colour_t.abs().max())
    d_grad = max(
        float((a - b).abs().max() / a.abs().max().clamp_min(1e-30))
        for a, b in zip(grads_t, grads_c, strict=True)
    )
    return d_colour, d_grad


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--counts", type=int, nargs="+", default=[5_000, 20_000])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=30)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)

    print(
        f"Shader float32, all terms, stand-in networks, {args.threads} threads, fastest of "
        f"{args.repeats} (ms)"
    )
    shader = make_shader()
    table = SpeedupTable("K")
    for count in args.counts:
        scene = Scene(count)
        speedups = table.measure(
            count,
            lambda backend, backward, sc=scene: step(shader, sc, backend, backward),
            args.repeats,
        )
        d_colour, d_grad = max_differences(shader, scene)
        table.agree = table.agree and d_colour < 1e-5 and d_grad < 1e-4
        print(
            f"{count:>6} {speedups}; relative max |Δ colour| {d_colour:.1e}, |Δ grad| {d_grad:.1e}"
        )
    print(table.summary("bench_shading", args.threads, TARGET))


if __name__ == "__main__":
    main()
