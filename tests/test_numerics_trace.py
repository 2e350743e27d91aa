"""benchmarks/numerics_trace.py: a trace follows the runner's training step for step; a comparison
names the first step, tensor and operation that differ (on a difference injected into one
operation's output)."""

from __future__ import annotations

import argparse
import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest
import test_runner_support as support
import torch
from torch.utils._python_dispatch import TorchDispatchMode

pytest.importorskip("olatbench.gaussians.shadow")  # SSD-GS's light-view pass

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "benchmarks" / "numerics_trace.py"
# a tiny SSD-GS job: 300 Gaussians, no density control within the run
SETTINGS = ["num_init_gaussians=300", "shadow_resolution=32", "densify_from=100000", "iterations=8"]


def load_script():
    spec = importlib.util.spec_from_file_location("numerics_trace", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def trace_tool():
    return load_script()


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return (
        support.write_tiny_data(tmp_path_factory.mktemp("trace") / "data", scenes=("Alpha",))
        / "Alpha"
    )


def job_args(data: Path, steps: int, ops_step: int | None = None) -> argparse.Namespace:
    return argparse.Namespace(
        method="ssdgs",
        suite="mini",
        data=str(data),
        scene=None,
        variant=None,
        seed=0,
        set=SETTINGS,
        steps=steps,
        ops_step=ops_step,
    )


def test_a_trace_follows_the_runners_training_step_for_step(trace_tool, data, tmp_path):
    from olatbench.bench.execute import run_job

    job = trace_tool.plan_job(job_args(data, 4), tmp_path / "runs")
    assert run_job(job, progress=False).status == "done", (
        Path(job.folder) / "error.txt"
    ).read_text()
    logged = [
        json.loads(line)["loss"]
        for line in (Path(job.folder) / "train_log.jsonl").read_text().splitlines()
    ]
    path = tmp_path / "trace.json"
    trace_tool.write_trace(path, trace_tool.record_trace(job_args(data, 4)))
    trace = trace_tool.read_trace(path)
    assert [step["step"] for step in trace["steps"]] == [0, 1, 2, 3, 4]  # 0: as set up
    # bit for bit, as the runner trained
    assert [step["loss"] for step in trace["steps"][1:]] == logged[:4]
    assert trace["job"]["id"] == job.id
    assert {"0.means", "0.opacity_logits"} <= set(trace["steps"][0]["params"]) and trace["steps"][
        1
    ]["grads"]
    assert trace["numerics"]["cpu_id"].keys() == {"vendor", "family", "model", "stepping"}
    assert trace["numerics"]["torch_cpu_capability"] == torch.backends.cpu.get_cpu_capability()
    # the same steps again: identical, and compare says so (exit 0)
    trace_tool.write_trace(tmp_path / "again.json", trace_tool.record_trace(job_args(data, 4)))
    assert trace_tool.main(["compare", str(path), str(tmp_path / "again.json")]) == 0


def test_compare_names_the_first_step_tensor_and_operation_of_an_injected_difference(
    trace_tool, data, tmp_path, monkeypatch, capsys
):
    """One operation of step 2 (the rasterizer's background term) gets its output moved by one ulp:
    compare names step 2, a tensor, and that operation, with equal inputs and different outputs."""
    trace_tool.write_trace(
        tmp_path / "a.json", trace_tool.record_trace(job_args(data, 3, ops_step=2))
    )
    injected: dict[str, object] = {}

    class OneUlp(TorchDispatchMode):
        """Below the recorder: the first aten.mul.Tensor's output moves one ulp up."""

        def __init__(self, recorder):
            super().__init__()
            self.recorder = recorder

        def __torch_dispatch__(self, func, types, args=(), kwargs=None):
            out = func(*args, **(kwargs or {}))
            if str(func) == "aten.mul.Tensor" and "index" not in injected:
                injected["index"] = len(self.recorder.ops)  # the recorder appends this op next
                out.copy_(torch.nextafter(out, torch.full_like(out, float("inf"))))
            return out

    class Injecting(trace_tool.OpRecorder):
        def __enter__(self):
            self.below = OneUlp(self)
            self.below.__enter__()
            return super().__enter__()

        def __exit__(self, *exc):
            super().__exit__(*exc)
            self.below.__exit__(*exc)

    monkeypatch.setattr(trace_tool, "OpRecorder", Injecting)
    trace_tool.write_trace(
        tmp_path / "b.json", trace_tool.record_trace(job_args(data, 3, ops_step=2))
    )
    a, b = trace_tool.read_trace(tmp_path / "a.json"), trace_tool.read_trace(tmp_path / "b.json")
    assert a["steps"][:2] == b["steps"][:2]  # set-up and step 1 untouched
    found = trace_tool.first_difference(a, b)
    assert found["step"] == 2 and found["tensor"] is not None
    assert found["ops"]["index"] == injected["index"] and found["ops"]["op"] == "aten.mul.Tensor"
    assert found["ops"]["cause"] == "rounds"
    assert trace_tool.main(["compare", str(tmp_path / "a.json"), str(tmp_path / "b.json")]) == 1
    printed = capsys.readouterr().out
    assert "first difference at step 2" in printed
    assert f"first op that differs: #{injected['index']} aten.mul.Tensor" in printed


def test_first_op_tells_a_kernel_written_input_from_a_rounding_op(trace_tool):
    op = {
        "op": "aten.mm.default",
        "where": "x.py:1 f",
        "shapes": [[2, 2]],
        "in": ["a1"],
        "out": ["b1"],
    }
    assert trace_tool.first_op([op], [dict(op)]) is None
    assert trace_tool.first_op([op], [{**op, "out": ["b2"]}])["cause"] == "rounds"
    assert trace_tool.first_op([op], [{**op, "in": ["a2"], "out": ["b2"]}])["cause"] == "input"
    assert trace_tool.first_op([op], [{**op, "op": "aten.bmm.default"}])["cause"] == "sequence"
    assert trace_tool.first_op([op], [op, op])["cause"] == "sequence"


def test_a_file_that_is_not_a_trace_gets_one_line_naming_it(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text(
        '{"format": "olatbench-numerics-trace/1", "tensors": {"grads": ["x"], "params": []}, '
        '"steps": [{"step": 1, "loss": 1.0, "grads": "", "params": ""}]}'
    )
    done = subprocess.run(
        [sys.executable, str(SCRIPT), "compare", str(bad), str(bad)], capture_output=True, text=True
    )
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert (
        done.stderr.startswith(f"numerics_trace: {bad}: not a numerics trace")
        and "0 grads for 1" in done.stderr
    )


def test_the_c_kernels_avx2_copy_and_their_baseline_copy_train_alike(data, tmp_path):
    """``settings`` records each side in a fresh process; here A runs olatbench's C++ kernels'
    16-byte copy (``OLATBENCH_NATIVE_SIMD=baseline``) and B the AVX2 copy they choose on an AVX2
    CPU. The copies do the same operations lane by lane without FMA (``_native/include/simd.h``), so
    the steps are identical on any CPU: a property of the code, not of the CPU's rounding (the tiny
    job runs every shading term from its second step)."""
    done = subprocess.run(
        [
            sys.executable,
            str(SCRIPT),
            "settings",
            "--data",
            str(data),
            "--steps",
            "3",
            *(f"--set={item}" for item in SETTINGS),
            "--a",
            "OLATBENCH_NATIVE_SIMD=baseline",
            "-o",
            str(tmp_path / "out"),
        ],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "identical over the 3 common steps and the set-up" in done.stdout
    assert "'OLATBENCH_NATIVE_SIMD': 'baseline'" in done.stdout


def test_tensor_hash_is_of_values_shape_and_dtype_not_of_memory_layout(trace_tool):
    values = torch.arange(6, dtype=torch.float32).reshape(2, 3)
    assert trace_tool.tensor_hash(values.t()) == trace_tool.tensor_hash(values.t().contiguous())
    assert trace_tool.tensor_hash(torch.tensor(3.0).expand(1)) == trace_tool.tensor_hash(
        torch.tensor([3.0])
    )
    assert trace_tool.tensor_hash(values) != trace_tool.tensor_hash(values.reshape(3, 2))
    assert trace_tool.tensor_hash(values) != trace_tool.tensor_hash(values.double())
    nudged = values.clone()
    nudged[1, 2] = torch.nextafter(nudged[1, 2], torch.tensor(float("inf")))
    assert trace_tool.tensor_hash(values) != trace_tool.tensor_hash(nudged)


def test_every_committed_trace_reads_and_names_its_cpu(trace_tool):
    """benchmarks/traces/<vendor>-<family>-<model>-<stepping>.json: what another CPU compares
    against (docs/runner.md); comparing it with itself names no difference."""
    traces = sorted((REPO / "benchmarks" / "traces").glob("*.json"))
    assert traces
    for path in traces:
        trace = trace_tool.read_trace(path)
        cpu = trace["numerics"]["cpu_id"]
        assert path.stem == f"{cpu['vendor']}-{cpu['family']}-{cpu['model']}-{cpu['stepping']}"
        assert trace["steps"][0]["step"] == 0 and len(trace["steps"]) > 1 and trace["commit"]
        assert trace_tool.first_difference(trace, trace) is None


@pytest.mark.slow
def test_this_cpus_committed_trace_repeats_to_the_last_bit(trace_tool, tmp_path):
    """Slow, and CPU-dependent by design: on a CPU (vendor, family, model, stepping) with a
    committed trace, the same steps recorded again as the olatbench command runs them
    (a fresh process, its pins) give the same bits wherever the threads and rounding variables are
    the trace's too (what README.md's "to the last digit on the CPU and thread count measured" rests
    on). Elsewhere it skips, naming why."""
    from olatbench.numerics import ROUNDING_ENV, cpu_id

    committed = [
        trace_tool.read_trace(path)
        for path in sorted((REPO / "benchmarks" / "traces").glob("*.json"))
    ]
    committed = [trace for trace in committed if trace["numerics"]["cpu_id"] == cpu_id()]
    if not committed:
        pytest.skip(f"no committed trace of this CPU ({cpu_id()}) in benchmarks/traces")
    reference = committed[0]
    job = reference["job"]
    out = tmp_path / "trace.json"
    done = subprocess.run(
        [
            sys.executable,
            str(SCRIPT),
            "record",
            "--method",
            job["method"],
            "--suite",
            job["suite"],
            "--scene",
            job["scene"],
            "--variant",
            job["variant"],
            "--seed",
            str(job["seed"]),
            "--steps",
            str(len(reference["steps"]) - 1),
            "-o",
            str(out),
        ],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    trace = trace_tool.read_trace(out)
    settings = ("torch_threads", "torch_cpu_capability", *ROUNDING_ENV)
    changed = [
        key for key in settings if trace["numerics"].get(key) != reference["numerics"].get(key)
    ]
    if changed:
        pytest.skip(f"this CPU's committed trace was made with other {', '.join(changed)}")
    assert trace_tool.first_difference(reference, trace) is None, trace_tool.comparison_text(
        reference, trace
    )[0]
