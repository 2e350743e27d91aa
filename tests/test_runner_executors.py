"""Executors: the local process pool and the Slurm path (submitit's local executor, including a
requeue)."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import time
from pathlib import Path

import pytest
import test_runner_support as support
from waiting import BACKSTOP_SECONDS, wait_until

from olatbench.bench.checkpoints import list_checkpoints
from olatbench.bench.executors import SlurmOptions, run_local, submit_slurm, wait_slurm
from olatbench.bench.plan import PlanOptions, make_plan
from olatbench.bench.results import read_results


@pytest.fixture()
def data(tmp_path):
    return support.write_tiny_data(tmp_path / "data")


@pytest.fixture()
def tests_on_pythonpath(monkeypatch):
    """Worker processes import the trivial method from tests/ (submitit starts plain `python
    -m`)."""
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
    metrics = [
        read_results(Path(jobs[0].folder) / "results.json")["metrics"] for jobs in (pooled, inline)
    ]
    assert metrics[0] == metrics[1]


def test_slurm_array_through_submitit_local_executor(data, tmp_path, tests_on_pythonpath):
    jobs = plan(data, tmp_path / "runs")
    submitted = submit_slurm(
        jobs,
        tmp_path / "runs",
        SlurmOptions(cluster="local", time_minutes=5, cpus=1, partition="ignored-locally"),
    )
    assert len(submitted) == 2
    outcomes = wait_slurm(submitted, jobs, progress=False)
    assert [o.status for o in outcomes] == ["done", "done"]
    for job in jobs:
        assert (Path(job.folder) / "DONE").read_text().strip() == job.id
    assert (tmp_path / "runs" / ".submitit").is_dir()


@pytest.mark.slow
@pytest.mark.skipif(
    not Path("/proc/self/task").is_dir(), reason="finds the task process through Linux /proc"
)
def test_slurm_preemption_requeues_and_resumes(data, tmp_path, tests_on_pythonpath):
    job = plan(
        data,
        tmp_path / "runs",
        scenes=["Alpha"],
        iterations=60,
        options=PlanOptions(checkpoint_every=5),
    )[0]
    slow = type(job)(**{**job.__dict__, "config": {**job.config, "step_sleep": 0.05}})
    task = submit_slurm(
        [slow], tmp_path / "runs", SlurmOptions(cluster="local", time_minutes=5, cpus=1)
    )[0]
    wait_until(
        lambda: list_checkpoints(job.folder) or task.done(), "first checkpoint of the Slurm task"
    )
    assert not task.done(), task.stderr()
    # Slurm preempts by sending USR2 to the task (submitit then calls checkpoint() and requeues).
    # submitit's local controller does not forward USR2 (LocalJob._interrupt would kill the
    # controller), so signal the task.
    children = (
        Path(f"/proc/{task._process.pid}/task/{task._process.pid}/children").read_text().split()
    )
    assert len(children) == 1
    os.kill(int(children[0]), signal.SIGUSR2)
    outcome = task.result()
    assert outcome.status == "done", outcome
    log = (Path(job.folder) / "log.txt").read_text()
    assert log.count("job " + job.id) == 2 and "resumed from step_" in log


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture()
def slurm_cluster(tmp_path, monkeypatch):
    """A one-node Slurm cluster on localhost (Debian's slurmctld + slurmd + munge), started for this
    test."""
    tools = ("munged", "slurmctld", "slurmd", "sbatch", "sinfo")
    if (
        not all(shutil.which(tool) for tool in tools)
        or os.geteuid() != 0
        or not Path("/etc/munge/munge.key").exists()
    ):
        pytest.skip("needs root and Debian's slurmctld, slurmd, slurm-client and munge")
    root = tmp_path / "slurm"
    munge = root / "munge"
    for folder in (root / "state", root / "spool", munge):
        folder.mkdir(parents=True)
    munge.chmod(0o700)
    host = socket.gethostname()
    conf = root / "slurm.conf"
    conf.write_text(
        "\n".join(
            [
                "ClusterName=olatbench-test",
                f"SlurmctldHost={host}",
                "SlurmUser=root",
                "SlurmdUser=root",
                "AuthType=auth/munge",
                f"AuthInfo=socket={munge / 'munge.socket'}",
                f"StateSaveLocation={root / 'state'}",
                f"SlurmdSpoolDir={root / 'spool'}",
                f"SlurmctldPidFile={root / 'ctld.pid'}",
                f"SlurmdPidFile={root / 'd.pid'}",
                f"SlurmctldPort={_free_port()}",
                f"SlurmdPort={_free_port()}",
                "ProctrackType=proctrack/linuxproc",
                "TaskPlugin=task/none",
                "MpiDefault=none",
                "SelectType=select/cons_tres",
                "SelectTypeParameters=CR_Core",
                "ReturnToService=2",
                "JobAcctGatherType=jobacct_gather/none",
                "AccountingStorageType=accounting_storage/none",
                f"SlurmctldLogFile={root / 'ctld.log'}",
                f"SlurmdLogFile={root / 'd.log'}",
                f"NodeName={host} CPUs={os.cpu_count()} State=UNKNOWN",
                f"PartitionName=olat Nodes={host} Default=YES MaxTime=INFINITE State=UP",
                "",
            ]
        )
    )
    processes = [
        subprocess.Popen(
            [
                "munged",
                "-F",
                "--force",
                f"--socket={munge / 'munge.socket'}",
                f"--pid-file={munge / 'pid'}",
                f"--log-file={munge / 'log'}",
                f"--seed-file={munge / 'seed'}",
            ]
        )
    ]
    wait_until(lambda: (munge / "munge.socket").exists(), "munged's socket")
    processes += [
        subprocess.Popen([daemon, "-D", "-f", str(conf)]) for daemon in ("slurmctld", "slurmd")
    ]
    monkeypatch.setenv("SLURM_CONF", str(conf))
    try:
        wait_until(
            lambda: (
                "idle"
                in subprocess.run(
                    ["sinfo", "-h", "-o", "%t"], capture_output=True, text=True
                ).stdout
            ),
            "idle Slurm node",
            poll=0.5,
        )
        yield root
        # let the job steps finish before their daemons go
        deadline = time.monotonic() + BACKSTOP_SECONDS
        while subprocess.run(["squeue", "-h"], capture_output=True, text=True).stdout.strip():
            if time.monotonic() > deadline:
                subprocess.run(["scancel", "--full", "--user=root"], check=False)
                break
            time.sleep(0.5)
    finally:
        for process in reversed(processes):
            process.terminate()
        for process in processes:
            process.wait(timeout=BACKSTOP_SECONDS)


@pytest.mark.slow
def test_run_cli_on_a_real_single_node_slurm_cluster(
    data, tmp_path, slurm_cluster, tests_on_pythonpath, monkeypatch
):
    from click.testing import CliRunner

    from olatbench.cli import main
    from olatbench.datasets import suites

    monkeypatch.setitem(suites.SUITES, "tiny", support.tiny_suite())
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
        "--quiet",
        "--device",
        "cpu",
        "--executor",
        "slurm",
        "--slurm-partition",
        "olat",
        "--slurm-time",
        "10",
        "--slurm-cpus",
        "1",
        "--wait",
    ]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    assert "submitted 2 task(s) as array" in result.output
    folders = sorted((tmp_path / "runs" / "tiny" / "trivial" / "default").glob("*/seed0"))
    assert len(folders) == 2 and all((folder / "DONE").is_file() for folder in folders)
    assert any((tmp_path / "runs" / ".submitit").rglob("*_log.out"))
