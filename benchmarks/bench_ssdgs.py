"""SSD-GS training-step speed on CPU: one full iteration split by stage, with two ratios from the
same run.

For each model state, resolution and Gaussian count the script times every stage below (fastest of
``--repeats`` rounds after a warm-up, the stages taking turns within each round) on one fixed model:
the learning rates are zeroed, so Adam does all its work but no stage changes the Gaussians another
stage sees (left free, the opacity reset due at the measured step made every Gaussian nearly
transparent and the rasterizer 2–3× faster from the second stage on). ``--states`` picks the models:

* ``initial``: SSD-GS's initialisation, N Gaussians uniform in the unit ball, opacity 0.1 (the start
  of training: much blending, few pixels terminate);
* ``surface``: a trained-looking object, N flat Gaussians (normal axis 0.1× the tangent ones)
  covering a sphere of radius 0.8 with opacity 0.9 (most pixels terminate after a few Gaussians);
* ``--jobs DIR ...``: trained SSD-GS models, each the final checkpoint of a job folder of
  ``olatbench run`` (its config, Gaussians and first training view; size and N are the job's),
  measured at its last iteration.

Stages:

* ``step``: one complete `SSDGS.train_step` with every term on and nothing frozen
  (densification off);
* ``rest``: the same step with the two networks swapped for free stand-ins (a constant that keeps
  the autograd graph through its inputs): everything else, measured on the real code path;
* ``mlp``: the two networks (Θ_SSS and Θ_shad, with their input encodings and the dipole) forward +
  backward on the visible Gaussians' inputs;
* ``matmul``: a bare chain of ``torch.addmm`` + ReLU with exactly the networks' layer shapes,
  forward + backward on the same batch (the reference for ``mlp``);
* ``raster``: projection + rasterization of 3 channels forward + backward alone
  (the reference for the rest);
* ``shadow``: the light-view visibility pass (forward only) and ``optimizer``: both Adam steps;
* contribution culling (``cull_shading``, one set per ``--cull-epsilons`` value ε): ``step`` with
  culling on at ε, ``mlp`` on the Gaussians it shades (those whose largest blending weight in the
  view exceeds ε), and ``cull``, the contribution pass alone
  (`olatbench.gaussians.contribution.max_weights`).

* bf16 networks (``network_precision="bf16"``, unless ``--no-bf16``): ``step``, ``mlp`` and
  ``matmul`` again with the networks (and the bare chain) under bf16 autocast; the line
  ``bf16 networks`` gives the step speed-up ``step / bf16 step`` as ``N.NNx`` (target ≥ 2 where AMX
  is present), the networks' speed-up, and their efficiency against this machine's bf16 matmul rate
  (``matmul@bf16 / mlp@bf16``, with both rates in GFLOP/s).

Ratios: ``mlp_efficiency = matmul / mlp`` (target ≥ 0.7) and ``rest_vs_raster = rest / raster``
(target ≤ 1.5). ``floor = (raster + shadow) / raster`` is what the camera pass and the light-view
pass alone cost in those units: the light-view pass is a forward rasterization at the view's size,
so no step that computes the coarse visibility every iteration gets below it. Per ε, an indented
line gives the Gaussians shaded, the culled step time and its speed-up ``step / culled step``
(target ≥ 2 on ``surface``), and the MLP share of the step (``mlp / step``) without and with
culling; every stage of a case, culled or not, takes turns in the same rounds. The last line is a
parseable summary. Example::

    python benchmarks/bench_ssdgs.py --repeats 3
    python benchmarks/bench_ssdgs.py --sizes 128 --counts 5000 --no-shadow   # no light-view pass
    python benchmarks/bench_ssdgs.py --light-view-scale 0.5          # light view at half the size
    python benchmarks/bench_ssdgs.py --states surface --sizes 256
    python benchmarks/bench_ssdgs.py --counts 20000 --cull-epsilons 0 0.001  # culled vs unculled
    python benchmarks/bench_ssdgs.py --states --jobs runs/mini/ssdgs/default/*/seed0  # trained
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import time
from collections.abc import Callable

import numpy as np
import torch

from olatbench.datasets.cameras import intrinsics_from_fov, look_at
from olatbench.datasets.records import Camera, PointLight
from olatbench.gaussians.contribution import max_weights
from olatbench.gaussians.projection import project
from olatbench.gaussians.rasterize import rasterize
from olatbench.gaussians.surface import place_on_sphere
from olatbench.methods.base import Views
from olatbench.methods.ssdgs import SSDGS
from olatbench.methods.ssdgs.config import SSDGSConfig
from olatbench.methods.training import camera_centre, shaded_subset

ALL_ON_STEP = 30_000  # Schedule I at 100K: every term on, nothing frozen


def timed(stages: dict[str, Callable[[], object]], repeats: int) -> dict[str, float]:
    """Seconds per stage: the fastest of ``repeats`` runs after a warm-up, the stages taking turns
    within each round so that every ratio compares samples taken under the same load
    (this machine is shared), and the minimum being the least disturbed sample of each."""
    for fn in stages.values():
        fn()  # warm-up
    samples: dict[str, list[float]] = {name: [] for name in stages}
    for _ in range(repeats):
        for name, fn in stages.items():
            start = time.perf_counter()
            fn()
            samples[name].append(time.perf_counter() - start)
    return {name: min(values) for name, values in samples.items()}


def make_method(
    size: int, count: int, use_shadow: bool, state: str, light_view_scale: float = 1.0
) -> SSDGS:
    """SSD-GS set up on one random view, its model put in ``state``, learning rates zeroed (the
    model stays fixed while Adam still does all its work), densification and opacity resets off; the
    light-view pass at ``light_view_scale`` × the view's size (1: the paper's setting)."""
    camera = Camera(
        K=intrinsics_from_fov(np.radians(45.0), size, size),
        c2w=look_at(np.array([0.0, -3.0, 1.0]), np.zeros(3)),
        width=size,
        height=size,
    )
    light = PointLight(
        position=np.array([2.0, -3.0, 3.0]), intensity=np.full(3, 16.0), intensity_known=True
    )
    rng = np.random.default_rng(0)
    views = Views(
        cameras=[camera],
        lights=[light],
        images=rng.random((1, size, size, 3), dtype=np.float32),
        frame_ids=["0"],
    )
    config = SSDGS.resolve_config(
        None,
        num_init_gaussians=count,
        init_radius=1.0,
        max_gaussians=None,
        densify_from=200_000,
        densify_until=200_000,
        opacity_reset_interval=1_000_000,
        use_shadow=use_shadow,
        shadow_resolution=round(size * light_view_scale),
    )
    method = SSDGS(config)
    method.setup(views, "cpu", 0)
    if state == "surface":
        put_on_sphere(method, radius=0.8, opacity=0.9)
    elif state != "initial":
        raise ValueError(f"unknown state {state!r}")
    freeze(method)
    return method


def freeze(method: SSDGS) -> None:
    """Zero every learning rate: Adam does all its work but the model stays fixed."""
    rates = method.learning_rates
    method.learning_rates = lambda step: dict.fromkeys(rates(step), 0.0)


def load_trained(folder: str) -> tuple[SSDGS, int]:
    """A job folder's trained SSD-GS (final checkpoint) with densification and opacity resets off,
    frozen and pinned to its first training view; and the step to measure (its last iteration: every
    term on)."""
    from olatbench.bench.restore import read_job, restore

    method_name = read_job(folder).method
    if method_name != "ssdgs":
        raise SystemExit(f"{folder}: a {method_name} job; this benchmark measures SSD-GS")
    method = restore(folder, train_images=True)[0]  # it takes training steps
    # statistics still gathered every step (as in the synthetic states), no density step ever
    never = 10**12
    method.densifier.config = dataclasses.replace(
        method.densifier.config,
        densify_from=never,
        densify_until=never,
        opacity_reset_interval=never,
    )
    freeze(method)
    method.train_views.next_index = lambda: 0  # every stage on the same view
    return method, method.config.iterations - 1


def put_on_sphere(method: SSDGS, radius: float, opacity: float) -> None:
    """Make the model a closed surface around the origin
    (`olatbench.gaussians.surface.place_on_sphere`)."""
    place_on_sphere(method.model, (0.0, 0.0, 0.0), radius, opacity)


class FreeNetwork(torch.nn.Module):
    """Stand-in for Θ_SSS / Θ_shad: 0.5 per Gaussian, still a function of the positions
    (graph kept)."""

    def forward(self, positions: torch.Tensor, *inputs: torch.Tensor) -> torch.Tensor:
        return positions[:, :1] * 0.0 + 0.5


def rest_stage(method: SSDGS, step: int) -> Callable[[], None]:
    """`train_step` with both networks replaced by `FreeNetwork` for the duration of each call."""
    shader = method.shader

    def run() -> None:
        networks = shader.sss_net, shader.shadow_net
        shader.sss_net, shader.shadow_net = FreeNetwork(), FreeNetwork()
        try:
            method.train_step(step)
        finally:
            shader.sss_net, shader.shadow_net = networks

    return run


def mlp_stage(method: SSDGS, visible: torch.Tensor) -> Callable[[], None]:
    """Θ_SSS and Θ_shad forward + backward on the visible Gaussians (random directions, fixed
    inputs)."""
    k = int(visible.numel())
    generator = torch.Generator().manual_seed(1)
    device = method.model.means.device
    positions = method.model.means.detach()[visible.to(device)]
    dirs = [
        torch.nn.functional.normalize(torch.randn(k, 3, generator=generator), dim=-1).to(device)
        for _ in range(3)
    ]
    material = method.model.attributes["material"].detach()[visible.to(device)].requires_grad_(True)
    coarse = torch.rand(k, 1, generator=generator).to(device)
    shader = method.shader

    def run() -> None:
        sss = shader.sss_net(positions, dirs[0], dirs[1], dirs[2], material)
        shadow = shader.shadow_net(positions, dirs[1], coarse, material)
        (sss.sum() + shadow.sum()).backward()

    return run


def matmul_chain(method: SSDGS, k: int) -> Callable[[], None]:
    """The same layer shapes as a bare addmm/ReLU chain (weights requiring grad), forward +
    backward."""
    chains = []
    for layers in (
        [m for m in method.shader.sss_net.network if isinstance(m, torch.nn.Linear)],
        list(method.shader.shadow_net.layers),
    ):
        weights = [
            (
                layer.weight.detach().clone().requires_grad_(True),
                torch.zeros(layer.out_features, requires_grad=True),
            )
            for layer in layers
        ]
        chains.append((torch.randn(k, layers[0].in_features), weights))

    def run() -> None:
        total = 0.0
        for x, weights in chains:
            for i, (w, b) in enumerate(weights):
                x = torch.addmm(b, x, w.T)
                if i < len(weights) - 1:
                    x = torch.relu(x)
            total = total + x.sum()
        total.backward()

    return run


def chain_flops(method: SSDGS, k: int) -> float:
    """Floating-point operations of `matmul_chain` on ``k`` rows: forward and the two backward
    matmuls per layer."""
    layers = [m for m in method.shader.sss_net.network if isinstance(m, torch.nn.Linear)]
    layers += list(method.shader.shadow_net.layers)
    return 3 * sum(2.0 * k * layer.in_features * layer.out_features for layer in layers)


def in_bf16(stage: Callable[[], None]) -> Callable[[], None]:
    """``stage`` under bf16 autocast (for the bare matmul chain)."""

    def run() -> None:
        with torch.autocast("cpu", dtype=torch.bfloat16):
            stage()

    return run


def with_precision(method: SSDGS, precision: str, stage: Callable[[], None]) -> Callable[[], None]:
    """``stage`` with both networks at ``precision`` (``network_precision``) for the duration of
    each call."""
    networks = method.shader.sss_net, method.shader.shadow_net

    def run() -> None:
        plain = [network.precision for network in networks]
        for network in networks:
            network.precision = precision
        try:
            stage()
        finally:
            for network, value in zip(networks, plain, strict=True):
                network.precision = value

    return run


def culled(method: SSDGS, epsilon: float, stage: Callable[[], None]) -> Callable[[], None]:
    """``stage`` with contribution culling on at ``epsilon`` for the duration of each call."""
    config = dataclasses.replace(method.config, cull_shading=True, cull_epsilon=epsilon)

    def run() -> None:
        plain, method.config = method.config, config
        try:
            stage()
        finally:
            method.config = plain

    return run


def shaded_by_culling(method: SSDGS, epsilon: float) -> torch.Tensor:
    """Indices of the Gaussians a culled step at ``epsilon`` shades on the method's (first) view."""
    views, model = method.train_views, method.model
    camera = views.views.cameras[0]
    projected = project(
        model.means,
        model.quats,
        model.scales,
        views.w2cs[0],
        views.Ks[0],
        camera.width,
        camera.height,
    )
    return shaded_subset(projected, model.opacities, epsilon)[0].indices


def cull_stage(method: SSDGS) -> Callable[[], None]:
    """The contribution pass alone (projection, binning and the max-weight compositing, forward
    only)."""
    model, views = method.model, method.train_views
    camera = views.views.cameras[0]

    def run() -> None:
        with torch.no_grad():
            projected = project(
                model.means,
                model.quats,
                model.scales,
                views.w2cs[0],
                views.Ks[0],
                camera.width,
                camera.height,
            )
            max_weights(projected, model.opacities)

    return run


def raster_stage(method: SSDGS) -> Callable[[], None]:
    model, views = method.model, method.train_views
    camera = views.views.cameras[0]
    features = torch.rand(model.num_gaussians, 3, device=model.means.device, requires_grad=True)

    def run() -> None:
        projected = project(
            model.means,
            model.quats,
            model.scales,
            views.w2cs[0],
            views.Ks[0],
            camera.width,
            camera.height,
        )
        out = rasterize(projected, model.opacities, features, method.background)
        out.image.sum().backward()

    return run


def shadow_stage(method: SSDGS) -> Callable[[], None]:
    from olatbench.gaussians.shadow import shadow_gather

    model, views = method.model, method.train_views
    camera = views.views.cameras[0]
    light = views.light_positions[0]
    options = method.light_view_options(
        views.Ks[0], camera.width, camera.height, camera_centre(views.w2cs[0]), light
    )

    def run() -> None:
        with torch.no_grad():
            shadow_gather(
                model.means,
                model.quats,
                model.scales,
                model.opacities,
                light,
                model.means.mean(0),
                **options,
            )

    return run


def optimizer_stage(method: SSDGS) -> Callable[[], None]:
    params = [*method.model.parameters(), *method.shader.parameters()]
    grads = [torch.zeros_like(p) for p in params]

    def run() -> None:
        # every parameter takes part, as in an all-on step
        for p, grad in zip(params, grads, strict=True):
            p.grad = grad
        method.gaussian_optimizer.step()
        method.global_optimizer.step()

    return run


def starting_clean(method: SSDGS, stage: Callable[[], None]) -> Callable[[], None]:
    """``stage`` after dropping every gradient a previous stage left behind (backward allocates, not
    adds)."""
    modules = (method.model, method.shader)

    def run() -> None:
        for module in modules:
            module.zero_grad(set_to_none=True)
        stage()

    return run


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sizes", type=int, nargs="+", default=[128, 256])
    parser.add_argument("--counts", type=int, nargs="+", default=[5_000, 20_000])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument(
        "--states",
        nargs="*",
        choices=["initial", "surface"],
        default=["initial", "surface"],
        help="synthetic model states to measure (see above); none with --jobs only",
    )
    parser.add_argument(
        "--jobs",
        nargs="+",
        default=[],
        metavar="DIR",
        help="job folders of trained SSD-GS runs to measure as well (their own config and size)",
    )
    parser.add_argument(
        "--no-shadow", action="store_true", help="composition without the shadow term"
    )
    parser.add_argument(
        "--light-view-scale",
        type=float,
        default=1.0,
        help="light-view pass size relative to the view (default 1: the view's size, as the paper)",
    )
    parser.add_argument("--no-bf16", action="store_true", help="skip the bf16-network stages")
    parser.add_argument(
        "--cull-epsilons",
        type=float,
        nargs="*",
        default=[0.0, SSDGSConfig().cull_epsilon],
        metavar="EPS",
        help="contribution-culling thresholds to measure as well (default: 0, exact, "
        "and the config's default); none to skip",
    )
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    torch.set_flush_denormal(True)
    efficiencies, rest_ratios, floors = [], [], []
    # per "state@ε": step / culled step of every size and count
    speedups: dict[str, list[float]] = {}
    bf16_speedups: list[float] = []  # step / bf16 step of every case
    print(
        f"{'state':>14} {'size':>5} {'N':>6} {'visible':>7} {'step':>8} {'rest':>8} {'mlp':>8} "
        f"{'matmul':>8} {'raster':>8} {'shadow':>8} {'optim':>8} {'mlp_eff':>8} {'rest/rast':>9} "
        f"{'floor':>6}"
    )

    def cases():
        for state, size, count in itertools.product(args.states, args.sizes, args.counts):
            yield (
                state,
                make_method(size, count, not args.no_shadow, state, args.light_view_scale),
                ALL_ON_STEP,
            )
        for folder in args.jobs:
            method, last = load_trained(folder)
            yield method.train_views.views.scene_name or "trained", method, last

    for state, method, at_step in cases():
        size, count = method.train_views.views.cameras[0].width, method.model.num_gaussians
        views = method.train_views
        camera = views.views.cameras[0]
        visible = torch.nonzero(
            project(
                method.model.means,
                method.model.quats,
                method.model.scales,
                views.w2cs[0],
                views.Ks[0],
                camera.width,
                camera.height,
            ).radii
            > 0
        ).squeeze(1)
        stages = {
            "step": lambda m=method, k=at_step: m.train_step(k),
            "rest": rest_stage(method, at_step),
            "mlp": mlp_stage(method, visible),
            "matmul": matmul_chain(method, int(visible.numel())),
            "raster": raster_stage(method),
            "optim": optimizer_stage(method),
        }
        if method.config.use_shadow:
            stages["shadow"] = shadow_stage(method)
        shaded = {eps: shaded_by_culling(method, eps) for eps in args.cull_epsilons}
        if shaded:
            stages["cull"] = cull_stage(method)
        for eps, subset in shaded.items():
            stages[f"step@{eps:g}"] = culled(
                method, eps, lambda m=method, k=at_step: m.train_step(k)
            )
            stages[f"mlp@{eps:g}"] = mlp_stage(method, subset)
        if not args.no_bf16:
            stages["step@bf16"] = with_precision(method, "bf16", stages["step"])
            stages["mlp@bf16"] = with_precision(method, "bf16", stages["mlp"])
            stages["matmul@bf16"] = in_bf16(matmul_chain(method, int(visible.numel())))
        times = timed(
            {name: starting_clean(method, fn) for name, fn in stages.items()}, args.repeats
        )
        step, rest_time, mlp, matmul, raster, optim = (
            times[k] for k in ("step", "rest", "mlp", "matmul", "raster", "optim")
        )
        shadow = times.get("shadow", float("nan"))
        efficiency, rest = matmul / mlp, rest_time / raster
        efficiencies.append(efficiency)
        rest_ratios.append(rest)
        floors.append((raster + (shadow if "shadow" in times else 0.0)) / raster)
        print(
            f"{state[:14]:>14} {size:>5} {count:>6} {visible.numel():>7} {step * 1e3:>7.1f}m "
            f"{rest_time * 1e3:>7.1f}m {mlp * 1e3:>7.1f}m {matmul * 1e3:>7.1f}m "
            f"{raster * 1e3:>7.1f}m {shadow * 1e3:>7.1f}m {optim * 1e3:>7.1f}m {efficiency:>8.2f} "
            f"{rest:>9.2f} {floors[-1]:>6.2f}"
        )
        if not args.no_bf16:
            flops = chain_flops(method, int(visible.numel()))
            step_b, mlp_b, matmul_b = times["step@bf16"], times["mlp@bf16"], times["matmul@bf16"]
            bf16_speedups.append(step / step_b)
            print(
                f"{'':>14} bf16 networks: step {step_b * 1e3:7.1f}m  speed-up "
                f"{step / step_b:4.2f}x  networks {mlp_b * 1e3:.1f}m (x{mlp / mlp_b:.2f})  "
                f"efficiency vs the bf16 matmul rate {matmul_b / mlp_b:.2f} (matmul: bf16 "
                f"{flops / matmul_b / 1e9:.1f}, fp32 {flops / matmul / 1e9:.1f} GFLOP/s)"
            )
        for eps, subset in shaded.items():
            step_c, mlp_c = times[f"step@{eps:g}"], times[f"mlp@{eps:g}"]
            speedups.setdefault(f"{state}@{eps:g}", []).append(step / step_c)
            print(
                f"{'':>14} cull eps={eps:<7g} shaded {subset.numel():>6}/{visible.numel():<6} step "
                f"{step_c * 1e3:7.1f}m  speed-up {step / step_c:5.2f}x  mlp share "
                f"{mlp / step:4.2f} -> {mlp_c / step_c:4.2f}  (pass {times['cull'] * 1e3:.1f}m)"
            )
    print(
        f"SUMMARY bench_ssdgs mlp_efficiency_min={min(efficiencies):.2f} (target>=0.7) "
        f"rest_vs_raster_max={max(rest_ratios):.2f} (target<=1.5; floor {max(floors):.2f}) "
        f"shadow={'off' if args.no_shadow else 'on'} light_view_scale={args.light_view_scale:g} "
        f"threads={args.threads}"
    )
    if bf16_speedups:
        from olatbench.methods.shading.precision import fast_bf16_cpu_flag

        print(
            f"SUMMARY bench_ssdgs bf16 step speed-up min {min(bf16_speedups):.2f}x max "
            f"{max(bf16_speedups):.2f}x (target>=2 with AMX; this CPU's bf16 instruction: "
            f"{fast_bf16_cpu_flag() or 'none (emulated)'})"
        )
    if speedups:
        ratios = " ".join(f"{key}={min(values):.2f}" for key, values in speedups.items())
        print(
            "SUMMARY bench_ssdgs culling speed-up (step / culled step, min over sizes and "
            f"counts): {ratios} (target>=2 on surface)"
        )


if __name__ == "__main__":
    main()
