"""Step-by-step parity of native ``ssdgs --variant official`` with the authors' unmodified SSD-GS
``train.py`` (and of ``gs3 --variant official`` with GS³'s, ``--method gs3``).

Both codes start from the same initial Gaussians, the same network weights and follow the same order
of training views, on one mini scene, and the harness prints per step both losses and their relative
difference, and at step N per parameter group the largest difference (issue #53, item 3)::

    python benchmarks/parity.py --scene aniso_metal --checkout /work/ext/ssdgs \\
        --python /work/ext/official-venv/bin/python \\
        [--steps 100] [--iterations 600] [--tolerance 1e-3]

How:

1. Both jobs are planned as ``olatbench run`` plans them (`make_plan`): ``ssdgs-official`` on
   ``mini`` with ``--iterations ITER --code device=cpu`` and ``ssdgs --variant
   official`` with ``--iterations ITER``, so the authors' flags and the native schedule are both
   compressed from the mini presets' 60K reference by `olatbench.methods.run_length.scaled_steps`.
   At the default ITER = 600 the shadow term switches on after iteration 50 and the SSS term at 90,
   inside the first 100 steps.
2. The official job's scene and train command come from the official runner (`prepare`: the
   converted scene, the 2000 initial points of the seed, the CPU stand-ins on ``PYTHONPATH``). The
   command runs through ``parity_hook/official_side.py`` (its docstring: it wraps three of the
   authors' functions at import time), which saves the initial state after ``training_setup``,
   records each iteration's view and loss, and saves the state after ``STEPS`` updates.
3. The native method is set up as the runner does (`prepare_method`, ``setup``); then its Gaussians
   and networks are overwritten with the authors' initial state (`native_tensors`: the authors'
   names and layouts in the native ones) and its view order is the recorded one
   (`TrainingViews` state); it takes ``STEPS`` steps.

Exit status: 0 when every step's relative loss difference is at most ``--tolerance``; 1 otherwise
(the first step that misses it is named); 2 for bad input or a failed official run.
"""

from __future__ import annotations

from olatbench.numerics import pin_numerics

pin_numerics()  # before torch is imported, as the olatbench command does

import argparse  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from collections.abc import Mapping, Sequence  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import torch  # noqa: E402

from olatbench.methods.official.cpu_standins.tcnn import (  # noqa: E402
    fully_fused_shapes,
    layer_weights,
)

HOOK = Path(__file__).resolve().parent / "parity_hook" / "official_side.py"
# native SSS output rows (σ_s, σ_a, r) from the authors' (r, σ_s', σ_a): scatter_mlp.py:43-49
SSS_ROWS = (1, 2, 0)


class ParityError(ValueError):
    """Bad input or a run that could not be compared (exit 2)."""


def frequency_columns(dims: int, frequencies: int) -> list[int]:
    """For each column of olatbench's `frequency_encoding` (all sines, then all cosines,
    frequency-major), the column of tiny-cuda-nn's Frequency encoding holding the same value (per
    input dimension, per frequency: sin, cos;
    `olatbench.methods.official.cpu_standins.tcnn.frequency_encoding`)."""
    return [
        d * 2 * frequencies + 2 * k + phase
        for phase in (0, 1)
        for k in range(frequencies)
        for d in range(dims)
    ]


def tcnn_weights(
    params: torch.Tensor, in_dim: int, out_dim: int, hidden: int, num_hidden: int, what: str
) -> list[torch.Tensor]:
    """The layer matrices [out, in] of a tiny-cuda-nn FullyFusedMLP's flat ``params`` (input padded
    to a multiple of 16, ``num_hidden`` hidden layers of ``hidden``, output padded to 16 rows:
    `cpu_standins.tcnn.Network`); a `ParityError` names ``what`` when the sizes do not fit."""
    shapes = fully_fused_shapes(in_dim, out_dim, hidden, num_hidden)
    if params.numel() != sum(rows * cols for rows, cols in shapes):
        raise ParityError(
            f"the authors' {what} has {params.numel()} parameters, not the "
            f"{sum(r * c for r, c in shapes)} of a {in_dim}-input {num_hidden}×{hidden} "
            "FullyFusedMLP"
        )
    return layer_weights(params, shapes)


def encoded_columns(in_dim: int, frequencies: int) -> list[int]:
    """The authors' first-layer columns in olatbench's input order: two frequency-encoded 3-vectors
    (`frequency_columns`), then the rest (material, and the shadow network's coarse visibility) as
    they are."""
    encoded = 3 * 2 * frequencies
    order = frequency_columns(3, frequencies)
    return [*order, *(encoded + c for c in order), *range(2 * encoded, in_dim)]


def first_layer(
    first: torch.Tensor, in_dim: int, frequencies: int, padded: bool, name: str
) -> dict[str, torch.Tensor]:
    """The authors' first layer [hidden, padded input] as the state of the native layer ``name``:
    its encoded columns reordered (`encoded_columns`); with ``padded`` the padded columns kept as
    they are, else their weights summed into ``name.bias`` (the same function)."""
    columns = encoded_columns(in_dim, frequencies)
    if padded:
        return {f"{name}.weight": torch.cat([first[:, columns], first[:, in_dim:]], dim=1)}
    return {f"{name}.weight": first[:, columns], f"{name}.bias": first[:, in_dim:].sum(dim=1)}


def shadow_layers(
    params: torch.Tensor,
    in_dim: int,
    hidden: int,
    num_hidden: int,
    frequencies: int,
    input_bias: str = "padded_ones",
) -> dict[str, torch.Tensor]:
    """The authors' shadow network (a tiny-cuda-nn FullyFusedMLP: one flat ``params``, input padded
    with ones to a multiple of 16, no biases, output padded to 16 rows) as the state of olatbench's
    `ShadowNetwork` with ``input_bias`` (``layers.<i>.weight``, ``layers.0.bias``): with
    "padded_ones" the same layout; with "vector" the padded columns' weights summed into the first
    layer's bias (the same function; not the same training, `olatbench.methods.shading.shadow_mlp`).
    The first layer's encoded columns are reordered (`encoded_columns`) for the two encoded
    3-vectors (light direction, position); material and coarse visibility follow in both."""
    weights = tcnn_weights(params, in_dim, 1, hidden, num_hidden, "shadow network")
    state = first_layer(weights[0], in_dim, frequencies, input_bias == "padded_ones", "layers.0")
    state.update({f"layers.{i}.weight": w for i, w in enumerate(weights[1:-1], start=1)})
    state[f"layers.{num_hidden}.weight"] = weights[-1][:1]
    return state


def other_layers(
    params: torch.Tensor,
    in_dim: int,
    hidden: int,
    num_hidden: int,
    frequencies: int,
    layout: str = "tiny_cuda_nn",
) -> dict[str, torch.Tensor]:
    """GS³'s other-effects network (a FullyFusedMLP like `shadow_layers`', 3 outputs) as the state
    of olatbench's `OtherEffectsNetwork` (``network.<2i>.weight``, and ``.bias`` in the "torch"
    layout) with ``layout``: "tiny_cuda_nn", the same layout; "torch", the padded columns' weights
    summed into the first bias and the other biases 0 — not the same function, since that layout has
    ReLU between its layers where tiny-cuda-nn has LeakyReLU(0.01), and its biases train where the
    authors' network has none."""
    weights = tcnn_weights(params, in_dim, 3, hidden, num_hidden, "other-effects network")
    state = first_layer(weights[0], in_dim, frequencies, layout == "tiny_cuda_nn", "network.0")
    for i, weight in enumerate(weights[1:], start=1):
        weight = weight[:3] if i == len(weights) - 1 else weight
        state[f"network.{2 * i}.weight"] = weight
        if layout != "tiny_cuda_nn":
            state[f"network.{2 * i}.bias"] = weight.new_zeros(len(weight))
    return state


def native_tensors(
    state: Mapping[str, torch.Tensor], layouts: Mapping[str, Mapping[str, object]]
) -> dict[str, torch.Tensor]:
    """The authors' model (``official_side.gaussian_state``) under the native names and layouts:
    per-Gaussian parameters as `GaussianModel.per_gaussian_parameters` names them, ``shader.<key>``
    as the shader's ``state_dict``; ``layouts``: the native networks' `shadow_layers` /
    `other_layers` arguments (`network_layouts`)."""
    out = {
        "means": state["_xyz"],
        "log_scales": state["_scaling"],
        "quats": state["_rotation"],
        "opacity_logits": state["_opacity"].reshape(-1),
        "attributes.diffuse": state["kd"],
        "attributes.specular": state["ks"],
        "attributes.asg_weights": state["alpha_asg"],
        "attributes.shading_quat": state["local_q"],
        "attributes.material": state["neural_material"],
        "shader.asg.raw_sigma": state["asg_sigma"],
        "shader.asg.raw_scales": state["asg_scales"],
        "shader.asg.rotation": state["asg_rotation"],
    }
    if "ksss" in state:
        out["attributes.sss"] = state["ksss"]
    linear = sorted({int(k.split(".")[2]) for k in state if k.startswith("scatter.network.")})
    for index in linear:
        weight, bias = (
            state[f"scatter.network.{index}.weight"],
            state[f"scatter.network.{index}.bias"],
        )
        if index == linear[-1]:
            weight, bias = weight[list(SSS_ROWS)], bias[list(SSS_ROWS)]
        (
            out[f"shader.sss_net.network.{index}.weight"],
            out[f"shader.sss_net.network.{index}.bias"],
        ) = weight, bias
    layers = shadow_layers(state["phasefunc.params"], **layouts["shadow"])  # type: ignore[arg-type]
    out.update({f"shader.shadow_net.{name}": value for name, value in layers.items()})
    if "other.params" in state:
        layers = other_layers(state["other.params"], **layouts["other"])  # type: ignore[arg-type]
        out.update({f"shader.other_net.{name}": value for name, value in layers.items()})
    return out


def network_layouts(method) -> dict[str, dict[str, object]]:
    """The `shadow_layers` (and, for GS³, `other_layers`) arguments of the native method's
    networks."""
    shadow = method.shader.shadow_net
    layouts: dict[str, dict[str, object]] = {
        "shadow": {
            "in_dim": shadow.in_dim,
            "hidden": shadow.layers[0].out_features,
            "num_hidden": len(shadow.layers) - 1,
            "frequencies": shadow.num_freqs,
            "input_bias": "padded_ones" if shadow.padding else "vector",
        }
    }
    other = getattr(method.shader, "other_net", None)
    if other is not None:
        linear = [layer for layer in other.network if isinstance(layer, torch.nn.Linear)]
        layouts["other"] = {
            "in_dim": linear[0].in_features - other.padding,
            "hidden": linear[0].out_features,
            "num_hidden": len(linear) - 1,
            "frequencies": other.num_freqs,
            "layout": "tiny_cuda_nn" if other.padding else "torch",
        }
    return layouts


def method_tensors(method) -> dict[str, torch.Tensor]:
    """The native method's parameters under the names of `native_tensors`
    (per-Gaussian, then the shader's)."""
    tensors = dict(method.model.per_gaussian_parameters())
    tensors.update({f"shader.{name}": value for name, value in method.shader.named_parameters()})
    return tensors


def load_native(method, tensors: Mapping[str, torch.Tensor]) -> None:
    """Overwrite the native method's parameters with ``tensors`` (`native_tensors`), in place (the
    optimisers keep their parameters; they have taken no step yet). A `ParityError` names a tensor
    that is missing or has another shape."""
    own = method_tensors(method)
    missing = sorted(set(own) - set(tensors))
    if missing:
        raise ParityError(f"the authors' state has no counterpart of {', '.join(missing)}")
    with torch.no_grad():
        for name, target in own.items():
            value = tensors[name]
            if value.shape != target.shape:
                raise ParityError(
                    f"{name}: the authors' tensor is {tuple(value.shape)}, the native one "
                    f"{tuple(target.shape)}"
                )
            target.copy_(value.to(target.dtype))


@dataclass(frozen=True)
class StepComparison:
    """Step ``step`` (from 1, the authors' iteration): both losses and
    ``|native - official| / |official|``."""

    step: int
    official: float
    native: float
    # the largest absolute difference of the two renders (before clipping)
    image: float = float("nan")

    @property
    def relative(self) -> float:
        return abs(self.native - self.official) / max(abs(self.official), 1e-12)


def first_miss(steps: Sequence[StepComparison], tolerance: float) -> StepComparison | None:
    """The first step whose relative loss difference exceeds ``tolerance`` (None: all within)."""
    return next((s for s in steps if not s.relative <= tolerance), None)


def largest_differences(
    official: Mapping[str, torch.Tensor], native: Mapping[str, torch.Tensor]
) -> dict[str, float | str]:
    """Per tensor name of ``official``: the largest absolute difference to ``native``, or why there
    is none (a missing tensor, another shape: densification made other Gaussians)."""
    out: dict[str, float | str] = {}
    for name, value in official.items():
        other = native.get(name)
        if other is None:
            out[name] = "missing in the native model"
        elif other.shape != value.shape:
            out[name] = f"shapes differ: official {tuple(value.shape)}, native {tuple(other.shape)}"
        else:
            out[name] = (
                float((other.detach().double() - value.double()).abs().max())
                if value.numel()
                else 0.0
            )
    return out


METHODS = ("ssdgs", "gs3")  # native methods with an official counterpart "<method>-official"


def plan_jobs(method: str, scene: str, iterations: int, checkout: str, python: str, out: Path):
    """The ``<method> --variant official`` and ``<method>-official`` (``device=cpu``) jobs of
    ``scene`` on mini."""
    from olatbench.bench.plan import PlanOptions, make_plan

    native = make_plan(
        method,
        "mini",
        out / "runs",
        scenes=[scene],
        variants=["official"],
        iterations=iterations,
        progress=False,
    )[0]
    code = {"checkout": checkout, "python": python, "device": "cpu"}
    official = make_plan(
        f"{method}-official",
        "mini",
        out / "runs",
        scenes=[scene],
        iterations=iterations,
        progress=False,
        options=PlanOptions(code=code),
    )[0]
    return native, official


def run_official(job, steps: int, out: Path) -> Path:
    """The authors' train command of ``job`` through the hook, for ``steps`` updates; returns the
    hook's folder."""
    from olatbench.datasets import load_scene
    from olatbench.methods.official.code import OfficialCode
    from olatbench.methods.official.runner import prepare
    from olatbench.methods.official.settings import CodeSettings
    from olatbench.methods.registry import get_spec
    from olatbench.methods.spec import import_reference

    code: OfficialCode = import_reference(job.method_ref)
    settings = CodeSettings.from_json(job.official)
    config = get_spec(job.method).resolve_config(None, **job.config)
    scene = load_scene(job.scene_path, format=job.scene_format)
    run = prepare(
        code,
        settings,
        scene,
        out / "official",
        job.suite,
        job.train_split,
        job.test_split,
        tuple(job.resolution) if job.resolution else None,
        config,
        job.seed,
    )
    [train] = [record for record in run.commands if record.step == "train"]
    hook_out = out / "hook"
    argv = [train.argv[0], str(HOOK), str(hook_out), str(steps), *train.argv[1:]]
    env = {**os.environ, **run.env, "OMP_NUM_THREADS": os.environ.get("OMP_NUM_THREADS", "1")}
    done = subprocess.run(argv, cwd=train.cwd, env=env, capture_output=True, text=True)
    (out / "official.log").write_text(done.stdout + done.stderr)
    if done.returncode != 0 or not (hook_out / "steps.json").is_file():
        raise ParityError(
            f"the authors' train.py failed (exit {done.returncode}); its output: "
            f"{out / 'official.log'}\n{(done.stdout + done.stderr)[-2000:]}"
        )
    return hook_out


def run_native(
    job, hook_out: Path, steps: int, authors_images: bool = False
) -> tuple[list[float], list[float], dict[str, torch.Tensor], object]:
    """The native method of ``job`` from the authors' initial state, along their recorded views:
    per-step losses, per step the largest absolute difference of its render (before clamping) to the
    authors' render of that iteration, the tensors after ``steps`` steps, the method. With
    ``authors_images`` the views the authors' code trained on are given the images its loader made
    (`use_authors_images`)."""
    from olatbench.bench.execute import prepare_method

    method, _, views, _ = prepare_method(job)
    if authors_images:
        use_authors_images(views, torch.load(hook_out / "targets.pt"))
    method.setup(views, job.device, job.seed)
    load_native(
        method, native_tensors(torch.load(hook_out / "initial.pt"), network_layouts(method))
    )
    records = json.loads((hook_out / "steps.json").read_text())
    index = {frame_id: i for i, frame_id in enumerate(views.frame_ids)}
    unknown = sorted({r["view"] for r in records} - set(index))
    if unknown:
        raise ParityError(
            f"the authors' views {', '.join(unknown[:3])} are not frames of the native job"
        )
    state = method.train_views.state_dict()
    method.train_views.load_state_dict(
        {**state, "order": torch.tensor([index[r["view"]] for r in records]), "cursor": 0}
    )
    renders = torch.load(hook_out / "renders.pt")  # (steps, 3, H, W)
    composites = (
        torch.load(hook_out / "composites.pt") if (hook_out / "composites.pt").is_file() else None
    )
    losses, images = [], []
    for step in range(min(steps, len(records))):
        # the forward pass train_step takes next (no state changes, no random numbers)
        with torch.no_grad():
            image = method.training_forward(index[records[step]["view"]], step)["image"]
        official = (
            composites[step] if composites is not None and method.shadow_on(step) else renders[step]
        )
        images.append(float((image.permute(2, 0, 1) - official).abs().max()))
        losses.append(float(method.train_step(step)["loss"]))
    return losses, images, method_tensors(method), method


def use_authors_images(views, targets: Mapping[str, torch.Tensor]) -> None:
    """Replace, in place, the images of ``views`` (N, H, W, 3) named in ``targets``
    (frame id -> (3, H, W)) by those. The authors' loader composites each RGBA PNG over the
    background and stores the result in 8 bits, truncated (``np.array(arr * 255.0, dtype=np.byte)``,
    scene/dataset_readers.py:164-166 at 26e4251), where olatbench keeps the float composite: on the
    mini scenes' partly transparent pixels up to 1/255 darker."""
    index = {frame_id: i for i, frame_id in enumerate(views.frame_ids)}
    for name, image in targets.items():
        if name not in index:
            raise ParityError(f"the authors' view {name} is not a frame of the native job")
        if tuple(image.shape) != (3, *views.images[index[name]].shape[:2]):
            raise ParityError(
                f"the authors' image of {name} is {tuple(image.shape)}, the native one "
                f"{views.images[index[name]].shape}"
            )
        views.images[index[name]] = image.permute(1, 2, 0).numpy()


def report(
    comparisons: Sequence[StepComparison],
    differences: Mapping[str, float | str],
    tolerance: float,
    events: Mapping[int, str],
) -> str:
    """The printed table: per step both losses, the relative difference and a mark where it exceeds
    ``tolerance`` (and the schedule's ``events`` at their steps); then the parameter differences."""
    lines = [f"{'step':>5} {'official':>12} {'native':>12} {'rel.diff':>10} {'image':>9}"]
    for s in comparisons:
        mark = "  <-- over" if not s.relative <= tolerance else ""
        event = f"  [{events[s.step]}]" if s.step in events else ""
        lines.append(
            f"{s.step:>5} {s.official:>12.7f} {s.native:>12.7f} {s.relative:>10.2e} {s.image:>9.2e}"
            f"{mark}{event}"
        )
    lines.append(f"largest absolute difference per tensor after step {len(comparisons)}:")
    lines += [
        f"  {name:<40} {value if isinstance(value, str) else f'{value:.3e}'}"
        for name, value in differences.items()
    ]
    return "\n".join(lines)


def schedule_events(method, steps: int) -> dict[int, str]:
    """The steps (from 1) at which the native method switches a term on, within ``steps``: SSD-GS's
    schedule (shadow, SSS, specular), GS³'s shadow phase."""
    if hasattr(method, "schedule"):
        terms = {
            term: (lambda step, term=term: method.schedule.is_enabled(term, step))
            for term in ("shadow", "sss", "specular")
        }
    else:
        terms = {"shadow": method.shadow_on}
    events: dict[int, list[str]] = {}
    for term, enabled in terms.items():
        on = next((s for s in range(steps) if enabled(s)), None)
        if on is not None and on > 0:
            events.setdefault(on + 1, []).append(f"{term} on")
    return {step: ", ".join(names) for step, names in events.items()}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--method",
        choices=METHODS,
        default="ssdgs",
        help="the native method; its official counterpart is <method>-official (default ssdgs)",
    )
    parser.add_argument("--scene", default="aniso_metal", help="mini scene (default aniso_metal)")
    parser.add_argument(
        "--checkout", required=True, help="the authors' checkout (SSD-GS 26e4251, GS³ 83c8daa)"
    )
    parser.add_argument("--python", required=True, help="the official environment's interpreter")
    parser.add_argument("--steps", type=int, default=100, help="steps compared (default 100)")
    parser.add_argument(
        "--iterations",
        type=int,
        default=600,
        help="run length both schedules are compressed to (default 600: shadow on after step 50)",
    )
    parser.add_argument(
        "--tolerance", type=float, default=1e-3, help="largest relative loss difference"
    )
    parser.add_argument("--out", help="keep the runs here (default: a temporary folder)")
    parser.add_argument(
        "--authors-images",
        action="store_true",
        help="train the native side on the images as the authors' loader made them (8-bit, "
        "truncated composite) instead of olatbench's float composite",
    )
    args = parser.parse_args(argv)
    if args.steps < 1 or args.iterations <= args.steps:
        print("parity: --steps must be at least 1 and below --iterations", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="parity-") as temporary:
        out = Path(args.out or temporary).resolve()
        out.mkdir(parents=True, exist_ok=True)
        try:
            native_job, official_job = plan_jobs(
                args.method, args.scene, args.iterations, args.checkout, args.python, out
            )
            hook_out = run_official(official_job, args.steps, out)
            losses, images, native_final, method = run_native(
                native_job, hook_out, args.steps, args.authors_images
            )
        except ParityError as error:
            print(f"parity: {error}", file=sys.stderr)
            return 2
        records = json.loads((hook_out / "steps.json").read_text())
        comparisons = [
            StepComparison(r["iteration"], float(r["loss"]), loss, image)
            for r, loss, image in zip(records, losses, images, strict=False)
        ]
        official_final = native_tensors(torch.load(hook_out / "final.pt"), network_layouts(method))
        print(
            report(
                comparisons,
                largest_differences(official_final, native_final),
                args.tolerance,
                schedule_events(method, args.steps),
            )
        )
    if len(comparisons) < args.steps:
        print(
            f"parity: only {len(comparisons)} of {args.steps} steps were recorded", file=sys.stderr
        )
        return 1
    worst = max(comparisons, key=lambda s: s.relative if s.relative == s.relative else float("inf"))
    print(f"parity: largest relative loss difference {worst.relative:.2e} at step {worst.step}")
    miss = first_miss(comparisons, args.tolerance)
    if miss is not None:
        print(
            f"parity: missed at step {miss.step}: relative loss difference {miss.relative:.2e} > "
            f"{args.tolerance:g} (official {miss.official:.7f}, native {miss.native:.7f})"
        )
        return 1
    print(f"parity: all {len(comparisons)} steps within {args.tolerance:g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
