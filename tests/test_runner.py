"""Running jobs: layout, results, skip, resume after SIGKILL (bit-exact), failure isolation, CLI,
status."""

from __future__ import annotations

import json
import os
import pickle
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import test_runner_support as support
import torch
from click.testing import CliRunner
from waiting import BACKSTOP_SECONDS, wait_until

from olatbench.bench.checkpoints import list_checkpoints
from olatbench.bench.execute import run_job
from olatbench.bench.executors import run_inline
from olatbench.bench.plan import PlanOptions, make_plan
from olatbench.bench.results import read_results
from olatbench.bench.store import find_results, job_state, scan_runs
from olatbench.cli import main
from olatbench.datasets import suites
from olatbench.datasets.images import read_image


@pytest.fixture()
def data(tmp_path):
    return support.write_tiny_data(tmp_path / "data")


@pytest.fixture()
def cli_suite(monkeypatch):
    """The tiny suite registered under the name 'tiny' for the CLI."""
    monkeypatch.setitem(suites.SUITES, "tiny", support.tiny_suite())


def plan(data, out, **kwargs):
    return make_plan("trivial", support.tiny_suite(), out, data_root=data, progress=False, **kwargs)


def test_end_to_end_layout_and_results(data, tmp_path):
    jobs = plan(data, tmp_path / "runs", options=PlanOptions(save_components=True))
    outcomes = run_inline(jobs, progress=False)
    assert [o.status for o in outcomes] == ["done", "done"]
    folder = Path(jobs[0].folder)
    assert (folder / "DONE").read_text().strip() == jobs[0].id
    results = read_results(folder / "results.json")
    assert results["status"] == "done" and results["job"]["id"] == jobs[0].id
    assert results["protocol"] == {"id": support.FAST_PROTOCOL, "version": 1}
    assert set(results["metrics"]) == {"train", "test"}
    assert set(results["metrics"]["test"]["per_image"]) == {"000", "001"}
    assert set(results["metrics"]["train"]["per_image"]) == {"000", "001", "002", "003"}
    mean = results["metrics"]["test"]["mean"]
    assert 5 < mean["psnr"] < 40 and mean["lpips"] is None
    assert results["model"] == {"iterations": 12, "num_gaussians": 64 * 48, "reused_from": None}
    assert results["timing"]["train_seconds"] > 0 and results["timing"]["render_fps"] > 0
    assert results["resources"]["peak_rss_mb"] > 50 and results["resources"]["cuda_peak_mb"] is None
    assert results["versions"]["torch"] == torch.__version__
    assert results["hashes"]["data_manifest"] == jobs[0].data_manifest
    assert results["hashes"]["data_matches_reference"] is None  # not the mini suite
    _check_provenance(results, folder, data / "Alpha")
    for split, count in (("train", 4), ("test", 2)):
        renders = sorted((folder / "renders" / split).glob("*.png"))
        assert len(renders) == count
        assert read_image(renders[0]).shape == (48, 64, 3)
    assert sorted(p.name for p in (folder / "components" / "test").iterdir()) == [
        "diffuse",
        "shadow",
    ]
    assert read_image(folder / "components" / "test" / "shadow" / "000.png").shape == (48, 64, 1)
    log = [json.loads(line) for line in (folder / "train_log.jsonl").read_text().splitlines()]
    assert [entry["step"] for entry in log] == list(range(1, 13))
    assert {"loss", "psnr", "seconds"} <= set(log[0])
    assert len(list_checkpoints(folder)) == 1  # only the final model stays
    assert json.loads((folder / "config.json").read_text())["iterations"] == 12
    assert "done" in (folder / "log.txt").read_text()
    assert find_results(tmp_path / "runs") == sorted(
        Path(job.folder) / "results.json" for job in jobs
    )


def _check_provenance(results, folder, scene_folder):
    """Schema 2: kind, start/end times, hardware, sha256 of the final checkpoint, the renders and
    the ground truth."""
    from datetime import datetime

    from olatbench.bench.results import Results
    from olatbench.metrics.evaluate import sha256_file

    assert results["schema_version"] == 2 and results["kind"] == "run" and results["source"] is None
    # all but official's
    assert set(Results.__annotations__) - {"method_kind", "official"} <= set(results)
    started, finished = (
        datetime.fromisoformat(results["timing"][key]) for key in ("started", "finished")
    )
    assert started.tzinfo is not None and started <= finished
    cpu = results["hardware"]["cpu"]
    assert (
        cpu["threads"] == os.cpu_count()
        and cpu["model"]
        and 1 <= cpu["usable_threads"] <= cpu["threads"]
    )
    assert (results["hardware"]["gpus"] == []) == (not torch.cuda.is_available())
    assert results["hashes"]["checkpoint"] == sha256_file(list_checkpoints(folder)[-1][1])
    test = results["files"]["test"]["000"]
    assert test["render"] == "renders/test/000.png"
    assert test["render_sha256"] == sha256_file(folder / "renders" / "test" / "000.png")
    assert Path(test["ground_truth"]).parent.parent == scene_folder.resolve()
    assert test["ground_truth_sha256"] == sha256_file(test["ground_truth"])
    assert set(results["files"]["train"]) == set(results["metrics"]["train"]["per_image"])


def test_metrics_match_the_saved_renders(data, tmp_path):
    """The per-image PSNR is the protocol's score of the render the job saved (8-bit sRGB)."""
    from olatbench.datasets import load_scene
    from olatbench.metrics.protocols import get_protocol

    job = plan(data, tmp_path / "runs", scenes=["Beta"])[0]
    run_job(job, progress=False)
    results = read_results(Path(job.folder) / "results.json")
    frame = load_scene(data / "Beta").split("test")[1]
    gt = frame.load(colourspace="srgb").rgb
    render = read_image(Path(job.folder) / "renders" / "test" / "001.png")
    expected = get_protocol(support.FAST_PROTOCOL).evaluate(render, gt)["psnr"]
    assert results["metrics"]["test"]["per_image"]["001"]["psnr"] == pytest.approx(
        expected, abs=1e-4
    )


def _weights(folder):
    step, path = list_checkpoints(folder)[-1]
    return step, torch.load(path, weights_only=True)["method"]


def _start_job(job, tmp_path):
    job_file = tmp_path / f"job-{time.monotonic_ns()}.pkl"
    job_file.write_bytes(pickle.dumps(job))
    # SIGINT as a terminal's Ctrl-C delivers it: a test run started in the background
    # (e.g. `pytest &`) would otherwise hand the child an ignored SIGINT, and the interruption would
    # never happen
    script = (
        f"import pickle, signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
        f"sys.path.insert(0, {str(support.TESTS)!r}); import test_runner_support; "
        f"from olatbench.bench.execute import run_job; "
        f"run_job(pickle.load(open({str(job_file)!r}, 'rb')), progress=False)"
    )
    return subprocess.Popen([sys.executable, "-c", script])


def _wait_for_checkpoint(process, folder):
    wait_until(
        lambda: list_checkpoints(folder), "first checkpoint of the job process", process=process
    )


@pytest.mark.parametrize(
    "sig", [signal.SIGKILL, pytest.param(signal.SIGINT, marks=pytest.mark.slow)]
)
def test_interrupted_job_resumes_to_the_uninterrupted_result(data, tmp_path, sig):
    kwargs = dict(scenes=["Alpha"], iterations=40, options=PlanOptions(checkpoint_every=5))
    reference = plan(data, tmp_path / "reference", **kwargs)[0]
    interrupted = plan(data, tmp_path / "interrupted", **kwargs)[0]
    assert reference.id == interrupted.id
    slow = {**interrupted.config, "step_sleep": 0.05}  # same id: only slows the first attempt down
    first_attempt = type(interrupted)(**{**interrupted.__dict__, "config": slow})

    process = _start_job(first_attempt, tmp_path)
    _wait_for_checkpoint(process, interrupted.folder)
    process.send_signal(sig)
    process.wait(timeout=BACKSTOP_SECONDS)
    state = job_state(interrupted.folder, interrupted.id)
    assert state.state == "partial" and 5 <= state.step < 40, state
    assert not (Path(interrupted.folder) / "error.txt").exists()

    assert run_job(interrupted, progress=False).status == "done"
    assert "resumed from step_" in (Path(interrupted.folder) / "log.txt").read_text()
    assert run_job(reference, progress=False).status == "done"

    resumed = read_results(Path(interrupted.folder) / "results.json")
    uninterrupted = read_results(Path(reference.folder) / "results.json")
    assert resumed["metrics"] == uninterrupted["metrics"]  # exact, not approximate
    step_a, weights_a = _weights(interrupted.folder)
    step_b, weights_b = _weights(reference.folder)
    assert step_a == step_b == 40
    assert torch.equal(weights_a["logits"], weights_b["logits"]) and torch.equal(
        weights_a["gain"], weights_b["gain"]
    )
    logs = [
        [
            json.loads(line)
            for line in (Path(job.folder) / "train_log.jsonl").read_text().splitlines()
        ]
        for job in (interrupted, reference)
    ]
    assert [(e["step"], e["loss"]) for e in logs[0]] == [(e["step"], e["loss"]) for e in logs[1]]


def test_a_failing_job_is_recorded_and_the_others_continue(data, tmp_path):
    jobs = plan(data, tmp_path / "runs", variants=["fails", "default"], scenes=["Alpha"])
    outcomes = run_inline(jobs, progress=False)
    assert [o.status for o in outcomes] == ["failed", "done"]
    assert "injected failure at step 3" in outcomes[0].error
    failed = Path(jobs[0].folder)
    assert "Traceback" in (failed / "error.txt").read_text()
    results = read_results(failed / "results.json")
    assert results["status"] == "failed" and results["metrics"] == {}
    assert results["error"] == {"type": "RuntimeError", "message": "injected failure at step 3"}
    assert not (failed / "DONE").exists()
    states = {s.folder.parts[-3]: s for s in scan_runs(tmp_path / "runs")}
    assert states["fails"].state == "failed" and "injected failure" in states["fails"].message
    assert states["default"].state == "done"


def test_cli_run_skips_done_jobs_and_exits_with_1_when_jobs_fail(data, tmp_path, cli_suite):
    runner = CliRunner()
    args = [
        "run",
        "--method",
        "trivial",
        "--suite",
        "tiny",
        "--data-root",
        str(data),
        "--out",
        str(tmp_path / "runs"),
        "--quiet",
        "--device",
        "cpu",
    ]
    result = runner.invoke(main, [*args, "--variant", "fails", "--variant", "default"])
    # not the count (2 failed here): 2 is click's usage error
    assert result.exit_code == 1, result.output
    assert "2 job(s) failed" in result.output and "FAILED Alpha/fails/seed0" in result.output
    assert "error.txt" in result.output
    assert "rerun the same command" in result.output
    done = tmp_path / "runs" / "tiny" / "trivial" / "default" / "Alpha" / "seed0" / "results.json"
    stamp = done.stat().st_mtime_ns

    result = runner.invoke(main, [*args, "--variant", "default"])
    assert result.exit_code == 0, result.output
    assert "2 already done, 0 to run" in result.output
    assert done.stat().st_mtime_ns == stamp
    assert "Alpha" in result.output and "done" in result.output  # the summary table

    # its own folder
    result = runner.invoke(main, [*args, "--variant", "default", "--iterations", "3"])
    assert result.exit_code == 0, result.output
    assert done.stat().st_mtime_ns == stamp
    short = (
        tmp_path
        / "runs"
        / "tiny"
        / "trivial"
        / "default~iterations=3"
        / "Alpha"
        / "seed0"
        / "results.json"
    )
    assert read_results(short)["model"]["iterations"] == 3

    # the scene's data changed: another job, same folder
    (data / "Alpha" / "notes.txt").write_text("changed")
    result = runner.invoke(main, [*args, "--variant", "default", "--scenes", "Alpha"])
    assert (
        result.exit_code == 2
        and "hold results of a different job" in result.output
        and "--force" in result.output
    )
    result = runner.invoke(main, [*args, "--variant", "default", "--scenes", "Alpha", "--force"])
    assert result.exit_code == 0, result.output
    assert (
        read_results(done)["hashes"]["data_manifest"]
        != read_results(short)["hashes"]["data_manifest"]
    )

    status = runner.invoke(main, ["status", str(tmp_path / "runs")])
    assert status.exit_code == 0, status.output
    assert "4 done, 2 failed" in status.output


def test_cli_dry_run_prints_the_table_without_running(data, tmp_path, cli_suite):
    result = CliRunner().invoke(
        main,
        [
            "run",
            "-m",
            "trivial",
            "-s",
            "tiny",
            "--data-root",
            str(data),
            "--out",
            str(tmp_path / "runs"),
            "--ablation",
            "schedule",
            "--seeds",
            "2",
            "--dry-run",
        ],
    )
    assert result.exit_code == 0, result.output
    # the table
    rows = [
        line for line in result.output.splitlines() if line[:1].isdigit() and "schedule-" in line
    ]
    assert len(rows) == 2 * 4 * 2 and all("pending" in row for row in rows)
    assert "16 job(s)." in result.output
    assert not (tmp_path / "runs").exists()


def test_cli_errors_are_one_line_with_a_next_step(data, tmp_path, cli_suite):
    runner = CliRunner()
    result = runner.invoke(main, ["run", "-m", "nope", "-s", "tiny", "--data-root", str(data)])
    assert (
        result.exit_code == 2
        and "olatbench methods list" in result.output
        and "Traceback" not in result.output
    )
    result = runner.invoke(
        main, ["run", "-m", "trivial", "-s", "tiny", "--variant", "zzz", "--data-root", str(data)]
    )
    assert "olatbench methods show trivial" in result.output
    result = runner.invoke(main, ["run", "-m", "trivial", "-s", "tiny", "--resolution", "big"])
    assert result.exit_code == 2 and "N or WxH" in result.output
    result = runner.invoke(main, ["status", str(tmp_path)])
    # no job: a usage error (docs/guarantees.md)
    assert result.exit_code == 2 and "olatbench run" in result.output
    result = runner.invoke(
        main, ["run", "-m", "trivial", "-s", "tiny", "--data-root", str(data), "--set", "lr"]
    )
    assert (
        result.exit_code == 2 and "KEY=VALUE" in result.output and "Traceback" not in result.output
    )
    result = runner.invoke(
        main, ["run", "-m", "trivial", "-s", "tiny", "--data-root", str(data), "--set", "x=1"]
    )
    assert result.exit_code == 2 and "no config field x" in result.output


def test_cli_set_overrides_show_in_the_plan(data, tmp_path, cli_suite):
    result = CliRunner().invoke(
        main,
        [
            "run",
            "-m",
            "trivial",
            "-s",
            "tiny",
            "--data-root",
            str(data),
            "--out",
            str(tmp_path / "runs"),
            "--set",
            "lr=0.5",
            "--dry-run",
        ],
    )
    assert result.exit_code == 0, result.output
    assert "default~lr=0.5" in result.output


def test_status_shows_partial_and_pending_jobs(data, tmp_path, cli_suite):
    jobs = plan(data, tmp_path / "runs", iterations=10, options=PlanOptions(checkpoint_every=4))
    ctrl_c = type(jobs[0])(
        **{**jobs[0].__dict__, "config": {**jobs[0].config, "interrupt_at_step": 6}}
    )
    with pytest.raises(KeyboardInterrupt):
        run_job(ctrl_c, progress=False)
    from olatbench.bench.session import write_pending

    write_pending(jobs[1:])
    result = CliRunner().invoke(main, ["status", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    assert "partial" in result.output and "4/10" in result.output and "pending" in result.output
    assert "1 partial, 1 pending" in result.output


def test_methods_cli_lists_and_shows_presets():
    runner = CliRunner()
    listed = runner.invoke(main, ["methods", "list"])
    assert listed.exit_code == 0 and "trivial" in listed.output
    shown = runner.invoke(main, ["methods", "show", "trivial"])
    assert shown.exit_code == 0, shown.output
    assert "iterations" in shown.output and "ablation-A: lr=0.01" in shown.output
    missing = runner.invoke(main, ["methods", "show", "nope"])
    assert missing.exit_code == 2 and "olatbench methods list" in missing.output


def test_a_job_running_elsewhere_is_skipped_not_touched(data, tmp_path):
    from olatbench.bench.store import job_lock

    job = plan(data, tmp_path / "runs", scenes=["Alpha"])[0]
    with job_lock(job.folder) as acquired:  # another process (here: another open file) runs the job
        assert acquired
        outcome = run_job(job, progress=False)
        assert outcome.status == "skipped" and "another process" in outcome.error
        assert job_state(job.folder).state == "running"
    assert not (Path(job.folder) / "results.json").exists()
    assert run_job(job, progress=False).status == "done"
    assert job_state(job.folder, job.id).state == "done"


def test_large_view_stacks_are_memory_mapped_with_the_same_result(data, tmp_path, monkeypatch):
    import numpy as np

    from olatbench.bench.execute import VIEWS_FILE, load_views
    from olatbench.datasets import load_scene

    in_ram = plan(data, tmp_path / "ram", scenes=["Beta"])[0]
    mapped = plan(data, tmp_path / "mapped", scenes=["Beta"])[0]
    frames = load_scene(data / "Beta").split("train")
    reference = load_views(frames, in_ram)
    monkeypatch.setenv("OLATBENCH_VIEWS_RAM_GB", "1e-6")
    Path(mapped.folder).mkdir(parents=True)
    views = load_views(frames, mapped)
    assert isinstance(views.images, np.memmap) and (Path(mapped.folder) / VIEWS_FILE).is_file()
    assert np.array_equal(views.images, reference.images) and not isinstance(
        reference.images, np.memmap
    )
    del views
    assert run_job(mapped, progress=False).status == "done"
    assert not (Path(mapped.folder) / VIEWS_FILE).exists()
    monkeypatch.delenv("OLATBENCH_VIEWS_RAM_GB")
    assert run_job(in_ram, progress=False).status == "done"
    results = [
        read_results(Path(job.folder) / "results.json")["metrics"] for job in (mapped, in_ram)
    ]
    assert results[0] == results[1]


def test_large_view_stacks_are_held_in_float16_and_scored_against_the_exact_images(
    data, tmp_path, monkeypatch
):
    """Above $OLATBENCH_VIEWS_HALF_GB the stack is float16 (within 2^-11 relative of float32); the
    train split is then scored against the images from disk, never against the rounded stack."""
    import numpy as np

    from olatbench.bench import execute
    from olatbench.datasets import load_scene

    job = plan(data, tmp_path / "half", scenes=["Beta"])[0]
    frames = load_scene(data / "Beta").split("train")
    reference = execute.load_views(frames, job)
    monkeypatch.setenv("OLATBENCH_VIEWS_HALF_GB", "1e-6")
    views = execute.load_views(frames, job)
    assert reference.images.dtype == np.float32 and views.images.dtype == np.float16
    assert np.abs(views.images.astype(np.float32) - reference.images).max() <= 2.0**-11 * max(
        1.0, float(reference.images.max())
    )
    given = {}
    real_evaluate_split = execute.evaluate_split

    def recording(method, frames, job, folder, split, gt_images, *args, **kwargs):
        given[split] = gt_images
        return real_evaluate_split(method, frames, job, folder, split, gt_images, *args, **kwargs)

    monkeypatch.setattr(execute, "evaluate_split", recording)
    assert run_job(job, progress=False).status == "done"
    assert given == {job.train_split: None, job.test_split: None}


def test_official_ground_truth_protocols_score_against_the_official_images(
    data, tmp_path, monkeypatch
):
    """A protocol whose ground truth is 'official' is scored against
    `Protocol.load_ground_truth`."""
    from dataclasses import replace

    from olatbench.metrics import protocols

    official = replace(
        protocols.get_protocol(support.FAST_PROTOCOL), id="test-official", ground_truth="official"
    )
    monkeypatch.setitem(protocols._PROTOCOLS, "test-official", official)
    calls = []
    original = type(official).load_ground_truth

    def spy(self, frame, scene_format, resolution=None):
        calls.append((frame.frame_id, scene_format))
        return original(self, frame, scene_format, resolution)

    monkeypatch.setattr(type(official), "load_ground_truth", spy)
    suite = support.tiny_suite(protocol="test-official")
    job = make_plan(
        "trivial", suite, tmp_path / "runs", data_root=data, scenes=["Beta"], progress=False
    )[0]
    run_job(job, progress=False)
    assert sorted(calls) == [(f, "nrhints") for f in ("000", "000", "001", "001", "002", "003")]


def _same_experiment_jobs(data, out, **overrides):
    """Two jobs of one experiment under two variant names: an override equal to the default renames
    the variant without changing the config."""
    first = plan(data, out, scenes=["Alpha"], overrides=dict(overrides))[0]
    second = plan(data, out, scenes=["Alpha"], overrides={**overrides, "lr": 0.1})[0]
    assert (
        first.variant != second.variant and first.config == second.config and first.id != second.id
    )
    return first, second


def test_a_job_of_a_finished_experiment_evaluates_its_model_instead_of_training(data, tmp_path):
    from olatbench.bench.reuse import experiment_key

    source, job = _same_experiment_jobs(data, tmp_path / "runs")
    assert experiment_key(source.identity()) == experiment_key(job.identity())
    assert run_job(source, progress=False).status == "done"
    assert run_job(job, progress=False).status == "done"
    folder, source_folder = Path(job.folder), Path(source.folder)
    results, source_results = (
        read_results(folder / "results.json"),
        read_results(source_folder / "results.json"),
    )
    assert results["job"]["id"] == job.id and results["job"]["variant"] == job.variant
    assert results["model"]["reused_from"] == {
        "job_id": source.id,
        "folder": f"../../../{source.variant}/Alpha/seed0",
    }
    assert source_results["model"]["reused_from"] is None
    # computed again in this folder, from the same weights
    assert results["metrics"] == source_results["metrics"]
    # what the model cost
    assert results["timing"]["train_seconds"] == source_results["timing"]["train_seconds"]
    (step, weights), (source_step, source_weights) = _weights(folder), _weights(source_folder)
    assert step == source_step and torch.equal(weights["logits"], source_weights["logits"])
    assert torch.load(list_checkpoints(folder)[-1][1], weights_only=True)["job_id"] == job.id
    assert (folder / "train_log.jsonl").read_text() == (
        source_folder / "train_log.jsonl"
    ).read_text()
    assert "same experiment as job " + source.id in (folder / "log.txt").read_text()
    assert job_state(job.folder, job.id).state == "done"


def test_reuse_needs_the_same_config_and_can_be_switched_off(data, tmp_path):
    import dataclasses

    runs = tmp_path / "runs"
    source = plan(data, runs, scenes=["Alpha"])[0]
    other = plan(data, runs, scenes=["Alpha"], overrides={"lr": 0.2})[0]  # another experiment
    assert run_job(source, progress=False).status == "done"
    assert run_job(other, progress=False).status == "done"
    assert read_results(Path(other.folder) / "results.json")["model"]["reused_from"] is None
    same = plan(data, runs, scenes=["Alpha"], overrides={"lr": 0.1})[0]
    assert run_job(dataclasses.replace(same, reuse=False), progress=False).status == "done"
    assert read_results(Path(same.folder) / "results.json")["model"]["reused_from"] is None
    assert "same experiment" not in (Path(same.folder) / "log.txt").read_text()


def test_a_job_waits_for_a_running_job_of_its_experiment_with_a_smaller_id(data, tmp_path):
    import threading

    from olatbench.bench.execute import JobLog, _run
    from olatbench.bench.store import job_lock

    first, second = _same_experiment_jobs(data, tmp_path / "runs", step_sleep=0.05)
    leader, follower = sorted((first, second), key=lambda job: job.id)
    outcome = {}
    with job_lock(leader.folder) as acquired:  # the leader runs "in another process"
        assert acquired
        Path(leader.folder, "job.json").write_text(json.dumps(leader.to_json()))
        thread = threading.Thread(
            target=lambda: outcome.update(done=run_job(follower, progress=False))
        )
        thread.start()
        _run(leader, Path(leader.folder), JobLog(Path(leader.folder)), False, 1, "now")
        assert thread.is_alive()  # it waits for the leader's lock, which is still held
    thread.join(timeout=BACKSTOP_SECONDS)
    assert outcome["done"].status == "done"
    results = read_results(Path(follower.folder) / "results.json")
    assert results["model"]["reused_from"]["job_id"] == leader.id


def test_parallel_executors_run_each_experiment_before_the_jobs_that_reuse_it(data, tmp_path):
    from olatbench.bench.reuse import order_for_reuse

    runs = tmp_path / "runs"
    same = plan(data, runs, overrides={"lr": 0.1})  # Alpha, Beta under "default~lr=0.1"
    jobs = plan(data, runs) + same + plan(data, runs, overrides={"lr": 0.3})
    ordered = order_for_reuse(jobs)
    assert [job.id for job in ordered] == [job.id for job in jobs[:2] + jobs[4:] + same]


def test_cli_dry_run_shows_which_jobs_reuse_a_model(data, tmp_path, cli_suite):
    runner = CliRunner()
    args = [
        "run",
        "-m",
        "trivial",
        "-s",
        "tiny",
        "--data-root",
        str(data),
        "--out",
        str(tmp_path / "runs"),
        "--scenes",
        "Alpha",
        "--quiet",
    ]
    assert runner.invoke(main, args).exit_code == 0
    result = runner.invoke(
        main, [*args, "--set", "lr=0.1", "--set", "noise=0.01", "--dry-run", "--json"]
    )
    assert result.exit_code == 0, result.output
    assert [row["reuse"] for row in json.loads(result.output)] == ["reuses default"]
    result = runner.invoke(
        main, [*args, "--variant", "tiny", "--variant", "ablation-A", "--dry-run"]
    )
    # the suite's own preset: "tiny" adds nothing to it
    assert "pending (reuses default)" in result.output
    fresh = [
        "run",
        "-m",
        "trivial",
        "-s",
        "tiny",
        "--data-root",
        str(data),
        "--out",
        str(tmp_path / "fresh"),
        "--scenes",
        "Alpha",
    ]
    result = runner.invoke(
        main, [*fresh, "--variant", "ablation-A", "--variant", "ablation-A+tiny", "--dry-run"]
    )
    assert "pending (same experiment as #0)" in result.output and "reuses" not in result.output
    result = runner.invoke(main, [*args, "--set", "lr=0.1", "--no-reuse", "--dry-run", "--json"])
    assert [row["reuse"] for row in json.loads(result.output)] == [None]
