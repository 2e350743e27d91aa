"""Executors: the local process pool and the Slurm path (submitit's local executor, including a requeue)."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest
import test_runner_support as support

from olatbench.bench.checkpoints import list_checkpoints
from olatbench.bench.executors import SlurmOptions, run_local, submit_slurm, wait_slurm
from olatbench.bench.plan import PlanOptions, make_plan
from olatbench.bench.results import read_results


@pytest.fixture()
def data(tmp_path):
    return support.write_tiny_data(tmp_path / "data")


@pytest.fixture()
def tests_on_pythonpath(monkeypatch):
    """Worker processes import the trivial method from tests/ (submitit starts plain `python -m`)."""
    monkeypatch.setenv("PYTHONPATH", str(support.TESTS))


def plan(data, out, **kwargs):
    return make_plan("trivial", support.tiny_suite(), out, data_root=data, progress=False, **kwargs)


def test_local_pool_runs_jobs_in_fresh_processes_and_isolates_failures(data, tmp_path):
    jobs = plan(data, tmp_path / "runs", variants=["default", "fails"], scenes=["Alpha"])
    outcomes = run_local(jobs, workers=2, progress=False)
    assert [o.status for o in outcomes] == ["done", "failed"]
    assert read_results(Path(jobs[0].folder) / "results.json")["status"] == "done"
    assert read_results(Path(jobs[1].folder) / "results.json")["status"] == "failed"


@pytest.mark.slow
def test_local_pool_matches_inline_results(data, tmp_path):
    from olatbench.bench.execute import run_job

    pooled = plan(data, tmp_path / "pool", scenes=["Beta"])
    inline = plan(data, tmp_path / "inline", scenes=["Beta"])
    run_local(pooled, workers=1, progress=False)
    run_job(inline[0], progress=False)
    metrics = [read_results(Path(jobs[0].folder) / "results.json")["metrics"] for jobs in (pooled, inline)]
    assert metrics[0] == metrics[1]


def test_slurm_array_through_submitit_local_executor(data, tmp_path, tests_on_pythonpath):
    jobs = plan(data, tmp_path / "runs")
    submitted = submit_slurm(jobs, tmp_path / "runs", SlurmOptions(cluster="local", time_minutes=5, cpus=1,
                                                                    partition="ignored-locally"))
    assert len(submitted) == 2
    outcomes = wait_slurm(submitted, jobs, progress=False)
    assert [o.status for o in outcomes] == ["done", "done"]
    for job in jobs:
        assert (Path(job.folder) / "DONE").read_text().strip() == job.id
    assert (tmp_path / "runs" / ".submitit").is_dir()


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="finds the task process through Linux /proc")
def test_slurm_preemption_requeues_and_resumes(data, tmp_path, tests_on_pythonpath):
    job = plan(data, tmp_path / "runs", scenes=["Alpha"], iterations=60, options=PlanOptions(checkpoint_every=5))[0]
    slow = type(job)(**{**job.__dict__, "config": {**job.config, "step_sleep": 0.05}})
    task = submit_slurm([slow], tmp_path / "runs", SlurmOptions(cluster="local", time_minutes=5, cpus=1))[0]
    deadline = time.monotonic() + 90
    while not list_checkpoints(job.folder):
        assert time.monotonic() < deadline and not task.done(), task.stderr()
        time.sleep(0.05)
    # Slurm preempts by sending USR2 to the task (submitit then calls checkpoint() and requeues). submitit's
    # local controller does not forward USR2 (LocalJob._interrupt would kill the controller), so signal the task.
    children = Path(f"/proc/{task._process.pid}/task/{task._process.pid}/children").read_text().split()
    assert len(children) == 1
    os.kill(int(children[0]), signal.SIGUSR2)
    outcome = task.result()
    assert outcome.status == "done", outcome
    log = (Path(job.folder) / "log.txt").read_text()
    assert log.count("job " + job.id) == 2 and "resumed from step_" in log
