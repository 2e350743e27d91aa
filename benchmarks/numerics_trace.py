"""Where does a training run start to round differently? Per-step (and per-op) hashes of a job's
first steps.

``record`` runs the first K training steps of one job exactly as ``olatbench run`` does (the same
plan, the same numerics pins before torch is imported, `olatbench.bench.execute.prepare_method`,
then ``setup`` and ``train_step``) and writes a JSON trace: per step the loss and a hash of every
gradient (taken just before each optimiser step) and of every parameter after the step (names:
``<optimiser index>.<group name>``, with ``.<k>`` for a group of several tensors), step 0 holding
the parameters as set up; with ``--ops-step S``, also every ATen operation of step S
(0: the set-up), through a ``TorchDispatchMode``: its name, where it ran (the innermost olatbench
source line in the forward pass, the autograd node in the backward pass), and hashes of its inputs
and outputs. The trace names the CPU (vendor, family, model, stepping, flags) and the numerics in
effect (`olatbench.numerics.cpu_numerics`).

``compare A B`` names the first step, the first tensor and (where both traces hold the ops of that
step) the first operation that differs. An operation whose inputs are equal and whose outputs differ
is where the rounding parts; an operation whose inputs already differ although every earlier
recorded operation's outputs matched reads a tensor made before the recorded step
(record the step before) or written outside torch's dispatcher (olatbench's C++ kernels write
through ctypes).

``settings`` does both for two settings of the environment on this CPU (e.g.
``ATEN_CPU_CAPABILITY=avx512`` against the default): it records each in a fresh process, compares,
and where they part at step S records step S's operations in both and names the first that differs.
Hashes are blake2b over a tensor's bytes, dtype and shape (10 hex digits). Examples::

    python benchmarks/numerics_trace.py record --scene diffuse_shadow --steps 300 -o trace.json
    python benchmarks/numerics_trace.py compare benchmarks/traces/GenuineIntel-6-207-2.json \\
        trace.json
    python benchmarks/numerics_trace.py settings --scene diffuse_shadow --steps 300 \\
        --a ATEN_CPU_CAPABILITY=avx512

Exit status: 0 when the traces (or settings) agree, 1 when they differ, 2 for bad input.
"""

from __future__ import annotations

from olatbench.numerics import pin_numerics

pin_numerics()  # before torch is imported, as the olatbench command does

import argparse  # noqa: E402
import hashlib  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from collections.abc import Callable, Iterator  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import torch  # noqa: E402
from torch.utils._python_dispatch import TorchDispatchMode  # noqa: E402
from torch.utils._pytree import tree_leaves  # noqa: E402

import olatbench  # noqa: E402
from olatbench.atomic import write_text  # noqa: E402
from olatbench.numerics import cpu_label, cpu_numerics  # noqa: E402

FORMAT = "olatbench-numerics-trace/1"
PACKAGE_ROOT = Path(olatbench.__file__).resolve().parent
#: Operations whose output is uninitialised memory: their bytes say nothing and are not hashed.
UNINITIALISED = (
    "aten.empty",
    "aten.empty_like",
    "aten.empty_strided",
    "aten.new_empty",
    "aten.new_empty_strided",
)


class TraceError(ValueError):
    """Bad input for the trace tool (the message names the file or option)."""


def tensor_hash(tensor: torch.Tensor) -> str:
    """10 hex digits of blake2b over ``tensor``'s bytes (row-major), dtype and shape."""
    data = tensor.detach()
    if data.layout != torch.strided or data.device.type == "meta":
        return f"<{data.layout} {data.device.type}>"
    # stride 1 (even a size-1 view)
    flat = data.cpu().reshape(-1).clone(memory_format=torch.contiguous_format)
    digest = hashlib.blake2b(
        flat.view(torch.uint8).numpy().tobytes() if flat.numel() else b"", digest_size=5
    )
    digest.update(f"{tuple(data.shape)} {data.dtype}".encode())
    return digest.hexdigest()


def optimizer_parameters(
    index: int, optimizer: torch.optim.Optimizer
) -> Iterator[tuple[str, torch.Tensor]]:
    """``(name, tensor)`` of every parameter of the ``index``-th optimiser, in its order
    (names: see the module docstring)."""
    for number, group in enumerate(optimizer.param_groups):
        name = f"{index}.{group.get('name', f'group{number}')}"
        params = group["params"]
        for k, param in enumerate(params):
            yield (name if len(params) == 1 else f"{name}.{k}"), param


def method_optimizers(method: Any) -> list[torch.optim.Optimizer]:
    """The method's optimisers: its ``optimizers`` (`GaussianMethod`), else every optimiser among
    its attributes."""
    found = getattr(method, "optimizers", None)
    if isinstance(found, (list, tuple)) and all(
        isinstance(o, torch.optim.Optimizer) for o in found
    ):
        return list(found)
    return [value for value in vars(method).values() if isinstance(value, torch.optim.Optimizer)]


def _where() -> str:
    """The autograd node running (backward), else the innermost olatbench source line on the stack
    (forward)."""
    node = torch._C._current_autograd_node()
    if node is not None:
        return node.name()
    frame = sys._getframe(2)
    while frame is not None:
        path = Path(frame.f_code.co_filename)
        if PACKAGE_ROOT in path.parents:
            return (
                f"{path.relative_to(PACKAGE_ROOT.parent).as_posix()}:{frame.f_lineno} "
                f"{frame.f_code.co_name}"
            )
        frame = frame.f_back
    return "?"


class OpRecorder(TorchDispatchMode):
    """Records every ATen operation: name, where (`_where`), input shapes, input and output
    hashes."""

    def __init__(self) -> None:
        super().__init__()
        self.ops: list[dict[str, Any]] = []

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        inputs = [leaf for leaf in tree_leaves((args, kwargs)) if isinstance(leaf, torch.Tensor)]
        record = {
            "op": str(func),
            "where": _where(),
            "shapes": [list(t.shape) for t in inputs],
            "in": [tensor_hash(t) for t in inputs],
        }
        out = func(*args, **kwargs)
        uninitialised = str(func).rsplit(".", 1)[0] in UNINITIALISED
        record["out"] = [
            "-" if uninitialised else tensor_hash(t)
            for t in tree_leaves(out)
            if isinstance(t, torch.Tensor)
        ]
        self.ops.append(record)
        return out


def plan_job(args: argparse.Namespace, out: Path):
    """The job ``olatbench run`` would run for these options (its folder below ``out``, never
    written)."""
    from olatbench.bench.plan import PlanError, make_plan, parse_overrides
    from olatbench.datasets.suites import data_suites, get_suite

    try:
        suite = data_suites([args.data])[0] if args.data else get_suite(args.suite)
        jobs = make_plan(
            args.method,
            suite,
            out,
            scenes=[args.scene] if args.scene else [],
            variants=[args.variant] if args.variant else [],
            seeds=args.seed + 1,
            progress=False,
            overrides=parse_overrides(args.set),
        )
    except (PlanError, KeyError, ValueError, FileNotFoundError) as error:
        raise TraceError(str(error.args[0] if isinstance(error, KeyError) else error)) from None
    jobs = [job for job in jobs if job.seed == args.seed]
    if len(jobs) != 1:
        raise TraceError(
            f"--scene: the plan has {len(jobs)} scenes ({', '.join(j.scene for j in jobs)}); name "
            "one"
        )
    if jobs[0].official is not None:
        raise TraceError(
            f"--method {args.method}: official code trains in its own process; it cannot be traced"
        )
    return jobs[0]


def record_trace(
    args: argparse.Namespace, reference: dict[str, Any] | None = None
) -> dict[str, Any]:
    """Run the first ``args.steps`` steps of the planned job; the trace (see the module docstring).
    With a ``reference`` trace (`read_trace`), stop after the first step that differs from it."""
    from olatbench.bench.execute import prepare_method

    commit = _commit()  # the code this process runs, before anything changes the checkout
    with tempfile.TemporaryDirectory(prefix="numerics-trace-") as folder:
        job = plan_job(args, Path(folder))
        method, _, views, _ = prepare_method(job)
        recorders: dict[int, OpRecorder] = {}

        def run(step: int, work: Callable[[], Any]) -> Any:
            """``work()``, its operations recorded when ``step`` is the ``--ops-step``."""
            if step != args.ops_step:
                return work()
            with OpRecorder() as recorder:
                recorders[step] = recorder
                return work()

        run(0, lambda: method.setup(views, job.device, job.seed))
        optimizers = method_optimizers(method)
        grads: dict[str, str] = {}

        def hash_grads(optimizer: torch.optim.Optimizer, *_: Any) -> None:
            grads.update(
                {
                    name: tensor_hash(param.grad)
                    for name, param in optimizer_parameters(optimizers.index(optimizer), optimizer)
                    if param.grad is not None
                }
            )

        def params() -> dict[str, str]:
            return {
                name: tensor_hash(param)
                for index, optimizer in enumerate(optimizers)
                for name, param in optimizer_parameters(index, optimizer)
            }

        for optimizer in optimizers:
            optimizer.register_step_pre_hook(hash_grads)
        reference_steps = (
            {step["step"]: step for step in reference["steps"]} if reference is not None else {}
        )
        steps = [{"step": 0, "loss": None, "grads": {}, "params": params()}]  # step 0: as set up
        for step in range(0, args.steps + 1):
            if step > 0:
                grads.clear()
                scalars = run(step, lambda step=step: method.train_step(step - 1))
                steps.append(
                    {
                        "step": step,
                        "loss": float(scalars["loss"]),
                        "grads": dict(grads),
                        "params": params(),
                    }
                )
            if (
                reference is not None
                and step in reference_steps
                and _step_differs(steps[-1], reference_steps[step])
            ):
                break  # the first step that differs from the reference: later steps add nothing
        ops = {"step": args.ops_step, "ops": recorders[args.ops_step].ops} if recorders else None
    names = {
        kind: list(dict.fromkeys(name for step in steps for name in step[kind]))
        for kind in ("grads", "params")
    }
    trace = {
        "format": FORMAT,
        "numerics": cpu_numerics(),
        "torch": torch.__version__,
        "olatbench": olatbench.__version__,
        "commit": commit,
        "job": {
            "id": job.id,
            "method": job.method,
            "suite": job.suite,
            "scene": job.scene,
            "variant": job.variant,
            "seed": job.seed,
            "iterations": job.iterations,
            "config": job.config,
        },
        "tensors": names,
        "steps": [
            {
                "step": step["step"],
                "loss": step["loss"],
                **{
                    kind: " ".join(step[kind].get(name, "-") for name in names[kind])
                    for kind in names
                },
            }
            for step in steps
        ],
    }
    if ops is not None:
        trace["ops"] = ops
    return trace


def _commit() -> str | None:
    """The olatbench checkout's git commit, ``+changes`` when tracked files differ from it
    (None outside git)."""
    try:
        head = subprocess.run(
            ["git", "-C", str(PACKAGE_ROOT), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            timeout=30,
        )
        changed = subprocess.run(
            ["git", "-C", str(PACKAGE_ROOT), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=30,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    if head.returncode != 0 or not head.stdout.strip():
        return None
    return head.stdout.strip() + ("+changes" if changed.stdout.strip() else "")


def read_trace(path: str | Path) -> dict[str, Any]:
    """A trace written by ``record``, each step's ``grads`` and ``params`` as ``{name: hash}``
    (absent tensors left out); `TraceError` naming the file for anything else."""
    try:
        trace = json.loads(Path(path).read_text(encoding="utf-8"))
        if trace.get("format") != FORMAT:
            raise ValueError(f"field 'format' is not {FORMAT!r}")
        for step in trace["steps"]:
            for kind in ("grads", "params"):
                hashes = step[kind].split()
                if len(hashes) != len(trace["tensors"][kind]):
                    raise ValueError(
                        f"step {step['step']}: {len(hashes)} {kind} for "
                        f"{len(trace['tensors'][kind])} names"
                    )
                step[kind] = {
                    name: h
                    for name, h in zip(trace["tensors"][kind], hashes, strict=True)
                    if h != "-"
                }
    except (OSError, ValueError, TypeError, KeyError, AttributeError) as error:
        raise TraceError(
            f"{path}: not a numerics trace ({type(error).__name__}: {error})"
        ) from None
    return trace


def write_trace(path: str | Path, trace: dict[str, Any]) -> None:
    """Write ``trace`` as JSON, one line per step (a committed trace stays short to read and to
    diff)."""
    head = json.dumps(
        {key: value for key, value in trace.items() if key != "steps"}, indent=1, allow_nan=False
    )
    steps = ",\n".join(f"  {json.dumps(step, allow_nan=False)}" for step in trace["steps"])
    write_text(path, f'{head[:-2]},\n "steps": [\n{steps}\n ]\n}}\n')


def _describe(trace: dict[str, Any]) -> str:
    numerics = trace["numerics"]
    pins = {k: v for k, v in numerics.items() if k.isupper() and v is not None}
    return (
        f"{cpu_label(numerics['cpu_id'])}, torch {trace['torch']} "
        f"({numerics['torch_cpu_capability']}, {numerics['torch_threads']} threads), pins "
        f"{pins or 'none'}, commit {trace.get('commit')}"
    )


def _step_differs(a: dict[str, Any], b: dict[str, Any]) -> bool:
    """Whether two steps' losses or hashes (``{name: hash}``) differ."""
    return a["loss"] != b["loss"] or a["grads"] != b["grads"] or a["params"] != b["params"]


def first_difference(a: dict[str, Any], b: dict[str, Any]) -> dict[str, Any] | None:
    """The first step where ``a`` and ``b`` differ: ``{"step", "loss": (a, b), "tensor", "kind",
    "differing", "ops"}`` (``tensor``: the first differing gradient, else parameter, in recorded
    order; ``ops``: `first_op` where both traces hold that step's operations), or None when every
    common step agrees."""
    steps_b = {step["step"]: step for step in b["steps"]}
    for step_a in a["steps"]:
        step_b = steps_b.get(step_a["step"])
        if step_b is None or not _step_differs(step_a, step_b):
            continue
        differing = [
            (kind, name)
            for kind in ("grads", "params")
            for name in dict.fromkeys([*step_a[kind], *step_b[kind]])
            if step_a[kind].get(name) != step_b[kind].get(name)
        ]
        ops = None
        if a.get("ops", {}).get("step") == step_a["step"] == b.get("ops", {}).get("step"):
            ops = first_op(a["ops"]["ops"], b["ops"]["ops"])
        kind, name = differing[0] if differing else (None, None)
        return {
            "step": step_a["step"],
            "loss": (step_a["loss"], step_b["loss"]),
            "kind": kind,
            "tensor": name,
            "differing": len(differing),
            "ops": ops,
        }
    return None


def first_op(a: list[dict[str, Any]], b: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The first operation of two recordings of one step that differs: ``{"index", "op", "where",
    "shapes", "cause"}``, cause ``"rounds"`` (equal inputs, different outputs), ``"input"`` (an
    input differs that no earlier recorded operation's output made differ: written outside the
    dispatcher) or ``"sequence"`` (another operation runs here); None when all agree."""
    for index, (op_a, op_b) in enumerate(zip(a, b, strict=False)):
        where = (
            op_a["where"]
            if op_a["where"] == op_b["where"]
            else f"{op_a['where']} / {op_b['where']}"
        )
        found = {"index": index, "op": op_a["op"], "where": where, "shapes": op_a["shapes"]}
        if op_a["op"] != op_b["op"]:
            return {**found, "op": f"{op_a['op']} / {op_b['op']}", "cause": "sequence"}
        if op_a["in"] != op_b["in"]:
            return {**found, "cause": "input"}
        if op_a["out"] != op_b["out"]:
            return {**found, "cause": "rounds"}
    if len(a) != len(b):
        return {
            "index": min(len(a), len(b)),
            "op": "(end of one recording)",
            "where": "",
            "shapes": [],
            "cause": "sequence",
        }
    return None


CAUSES = {
    "rounds": "equal inputs, different outputs: the rounding parts here",
    "input": "an input differs although every earlier recorded operation agreed: made before this "
    "step (record the step before, or 0 for the set-up) or written outside torch's dispatcher (a "
    "C++ kernel through ctypes)",
    "sequence": "another operation runs here",
}


def comparison_text(
    a: dict[str, Any], b: dict[str, Any], names: tuple[str, str] = ("A", "B")
) -> tuple[str, bool]:
    """(report, whether the traces agree) for two traces."""
    lines = [f"{name}: {_describe(trace)}" for name, trace in zip(names, (a, b), strict=True)]
    if a["job"]["id"] != b["job"]["id"]:
        lines.append(
            f"note: different jobs ({a['job']['id']} vs {b['job']['id']}; config or code differ)"
        )
    common = {step["step"] for step in a["steps"]} & {step["step"] for step in b["steps"]}
    found = first_difference(a, b)
    if found is None:
        lines.append(
            f"identical over the {len(common - {0})} common "
            f"steps{' and the set-up' if 0 in common else ''} (losses, gradients and parameters)"
        )
        return "\n".join(lines), True
    loss = (
        "as set up" if found["step"] == 0 else f"loss {found['loss'][0]!r} vs {found['loss'][1]!r}"
    )
    lines.append(
        f"first difference at step {found['step']} ({loss}): "
        + (
            f"first tensor {found['kind'][:-1]} {found['tensor']} ({found['differing']} differ)"
            if found["tensor"]
            else "every tensor equal"
        )
    )
    op = found["ops"]
    if op is not None:
        lines.append(
            f"first op that differs: #{op['index']} {op['op']} at {op['where']} (input shapes "
            f"{op['shapes']}): {CAUSES[op['cause']]}"
        )
    elif a.get("ops") or b.get("ops"):
        lines.append(
            f"(no per-op recording of step {found['step']} in both traces; record it with "
            f"--ops-step {found['step']})"
        )
    return "\n".join(lines), False


def _env_setting(text: str) -> dict[str, str]:
    """``"K=V K2=V2"`` as a dict (empty for "")."""
    pairs = text.split()
    if any("=" not in pair for pair in pairs):
        raise TraceError(f"--a/--b: {text!r} is not a list of NAME=VALUE")
    return dict(pair.split("=", 1) for pair in pairs)


def _record_args(args: argparse.Namespace) -> list[str]:
    """The ``record`` options of ``args`` (for a fresh process)."""
    options = ["--method", args.method, "--seed", str(args.seed)]
    options += ["--data", args.data] if args.data else ["--suite", args.suite]
    options += ["--scene", args.scene] if args.scene else []
    options += ["--variant", args.variant] if args.variant else []
    for item in args.set:
        options += ["--set", item]
    return options


def compare_settings(args: argparse.Namespace) -> tuple[str, bool]:
    """Record under settings A and B in fresh processes (steps, then the first differing step's
    operations)."""
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    settings = {"a": _env_setting(args.a), "b": _env_setting(args.b)}

    def record(name: str, steps: int, ops_step: int | None) -> dict[str, Any]:
        path = out / f"{name}{'' if ops_step is None else f'-ops{ops_step}'}.json"
        command = [
            sys.executable,
            __file__,
            "record",
            *_record_args(args),
            "--steps",
            str(steps),
            "-o",
            str(path),
        ]
        if ops_step is not None:
            command += ["--ops-step", str(ops_step)]
        environment = {**os.environ, **settings[name]}
        done = subprocess.run(command, env=environment, capture_output=True, text=True)
        if done.returncode != 0:
            raise TraceError(
                f"record under {settings[name] or 'the default'} failed: "
                f"{done.stderr.strip()[-2000:]}"
            )
        return read_trace(path)

    a, b = record("a", args.steps, None), record("b", args.steps, None)
    names = (f"A {settings['a'] or '(default)'}", f"B {settings['b'] or '(default)'}")
    text, same = comparison_text(a, b, names)
    found = first_difference(a, b)
    if found is not None:
        step = found["step"]
        text, same = comparison_text(record("a", step, step), record("b", step, step), names)
    return text, same


def _add_job_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--method", default="ssdgs")
    parser.add_argument("--suite", default="mini", help="a suite name (default mini)")
    parser.add_argument(
        "--data", help="a scene folder instead of --suite (as olatbench run --data)"
    )
    parser.add_argument("--scene", help="the scene (needed where the suite has several)")
    parser.add_argument("--variant", help="the method's variant (default: the suite's)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="config overrides"
    )
    parser.add_argument(
        "--steps", type=int, default=300, help="training steps to trace (default 300)"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    commands = parser.add_subparsers(dest="command", required=True)
    record = commands.add_parser("record", help="trace the first steps of a job")
    _add_job_options(record)
    record.add_argument(
        "--ops-step",
        type=int,
        help="also record every operation of this step (1-based; 0: the method's set-up)",
    )
    record.add_argument(
        "--until-differs", metavar="TRACE", help="stop after the first step that differs from TRACE"
    )
    record.add_argument("-o", "--output", required=True, help="the trace file to write (JSON)")
    compare = commands.add_parser(
        "compare", help="name the first step, tensor and op where two traces differ"
    )
    compare.add_argument("traces", nargs=2)
    settings = commands.add_parser("settings", help="compare two environment settings on this CPU")
    _add_job_options(settings)
    settings.add_argument(
        "--a", default="", help="environment of A, e.g. 'ATEN_CPU_CAPABILITY=avx512'"
    )
    settings.add_argument(
        "--b", default="", help="environment of B (default: as this process has it)"
    )
    settings.add_argument(
        "-o", "--output", default="numerics-traces", help="folder for the four traces"
    )
    args = parser.parse_args(argv)
    try:
        if args.command == "record":
            if args.steps < 0 or (
                args.ops_step is not None and not 0 <= args.ops_step <= args.steps
            ):
                raise TraceError(
                    f"--steps {args.steps} / --ops-step {args.ops_step}: need 0 <= ops-step <= "
                    "steps"
                )
            trace = record_trace(
                args, read_trace(args.until_differs) if args.until_differs else None
            )
            write_trace(args.output, trace)
            print(
                f"wrote {args.output}: {len(trace['steps'])} steps of {trace['job']['scene']} on "
                f"{_describe(trace)}"
            )
            return 0
        if args.command == "compare":
            text, same = comparison_text(*map(read_trace, args.traces), names=tuple(args.traces))
        else:
            text, same = compare_settings(args)
    except TraceError as error:
        print(f"numerics_trace: {error}", file=sys.stderr)
        return 2
    print(text)
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
