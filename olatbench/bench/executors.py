"""Executors: run a list of jobs inline, in a local process pool, or as one Slurm job array
(submitit).

Every executor calls `olatbench.bench.execute.run_job`, which records failures in the job folder
instead of raising, so one failing job never stops the others.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.connection import wait as connection_wait
from pathlib import Path
from typing import TYPE_CHECKING

from olatbench.bench.jobs import Job
from olatbench.progress import progress_bar

# the job runner imports torch: loaded when a job runs, not when the CLI lists executors
if TYPE_CHECKING:
    from olatbench.bench.outcome import JobOutcome

EXECUTORS = ("inline", "local", "slurm")
STOP_GRACE_SECONDS = 10.0  # how long a stopped worker gets to end after SIGTERM before it is killed
OnOutcome = Callable[["JobOutcome"], None]


def run_inline(
    jobs: Sequence[Job], progress: bool = True, on_outcome: OnOutcome | None = None
) -> list[JobOutcome]:
    """Run the jobs one after another in this process."""
    from olatbench.bench.execute import run_job

    outcomes = []
    with progress_bar(
        total=len(jobs), desc="jobs", position=0, disable=not progress, unit="job"
    ) as bar:
        for job in jobs:
            bar.set_postfix_str(job.label)
            outcome = run_job(job, progress=progress, position=1)
            outcomes.append(outcome)
            if on_outcome:
                on_outcome(outcome)
            bar.update(1)
    return outcomes


class Terminated(KeyboardInterrupt):
    """SIGTERM reached the process running the local executor: its workers were stopped (their jobs
    stay partial and resume on the next run) and their locks released. A `KeyboardInterrupt`, so it
    ends a run as Ctrl-C does."""


def _worker(job: Job, sender: Connection, slot: int, progress: bool, threads: int) -> None:
    """Run one job in its own process and send its outcome back; ``slot`` is the tqdm row of the
    per-job bar."""
    import torch

    from olatbench.bench.execute import run_job

    torch.set_num_threads(threads)
    try:
        sender.send(run_job(job, progress=progress, position=slot))
    # Ctrl-C reaches the whole process group: the job stays partial, the parent reports
    except KeyboardInterrupt:
        sys.exit(130)


@dataclass
class _Running:
    """One worker process of `run_local` and what it runs."""

    index: int
    job: Job
    process: multiprocessing.process.BaseProcess
    receiver: Connection
    slot: int


def _died(running: _Running) -> JobOutcome:
    """The outcome of a worker process that ended without reporting one (killed, crashed, out of
    memory)."""
    from olatbench.bench.outcome import JobOutcome

    code = running.process.exitcode
    how = (
        f"killed by signal {signal.Signals(-code).name}"
        if code is not None and code < 0
        else f"exit code {code}"
    )
    return JobOutcome(
        running.job.id,
        running.job.label,
        running.job.folder,
        "failed",
        recorded=False,
        error=f"worker process died ({how}); the next run resumes the job from its last checkpoint",
    )


@contextmanager
def _sigterm_as_terminated() -> Iterator[None]:
    """Within: SIGTERM raises `Terminated` in the main thread (elsewhere: nothing changes)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def terminated(signum, frame):
        raise Terminated

    previous = signal.signal(signal.SIGTERM, terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _stop(workers: dict[int, _Running]) -> None:
    """Stop every worker (SIGTERM, then SIGKILL after `STOP_GRACE_SECONDS`) and wait for each to
    end: the kernel releases the job locks of a process that ends, however it ends."""
    for running in workers.values():
        running.process.terminate()
    for running in workers.values():
        running.process.join(STOP_GRACE_SECONDS)
        if running.process.is_alive():
            running.process.kill()
            running.process.join()
        running.receiver.close()


def run_local(
    jobs: Sequence[Job], workers: int, progress: bool = True, on_outcome: OnOutcome | None = None
) -> list[JobOutcome]:
    """Run the jobs in up to ``workers`` spawned processes at once, a fresh one per job (honest peak
    memory, and isolation: a worker that dies — a segfault, the OOM killer, SIGKILL — fails its own
    job only, as ``worker process died (killed by signal SIGKILL)``); torch threads are shared out
    between the workers.

    Ctrl-C or SIGTERM to this process stops every worker (their jobs stay partial and resume on the
    next run), waits for them to end (so their job locks are released) and raises
    `KeyboardInterrupt` (`Terminated` for SIGTERM). No process outlives the call.
    """
    context = multiprocessing.get_context("spawn")
    threads = max(1, (os.cpu_count() or 1) // workers)
    waiting = list(enumerate(jobs))
    free_slots = list(range(1, workers + 1))
    active: dict[int, _Running] = {}
    outcomes: dict[int, JobOutcome] = {}
    with (
        _sigterm_as_terminated(),
        progress_bar(
            total=len(jobs), desc="jobs", position=0, disable=not progress, unit="job"
        ) as bar,
    ):
        try:
            while waiting or active:
                while waiting and len(active) < workers:
                    index, job = waiting.pop(0)
                    receiver, sender = context.Pipe(duplex=False)
                    slot = free_slots.pop(0)
                    process = context.Process(
                        target=_worker,
                        args=(job, sender, slot, progress, threads),
                        name=f"olatbench-job-{job.label}",
                    )
                    process.start()
                    sender.close()  # the child holds the only write end: its death closes the pipe
                    active[index] = _Running(index, job, process, receiver, slot)
                connection_wait([running.receiver for running in active.values()])
                for running in [r for r in active.values() if r.receiver.poll()]:
                    try:
                        outcome = running.receiver.recv()
                    except EOFError:  # the pipe closed without an outcome: the process died
                        running.process.join()
                        outcome = _died(running)
                    else:
                        running.process.join()
                    running.receiver.close()
                    del active[running.index]
                    free_slots.append(running.slot)
                    outcomes[running.index] = outcome
                    if on_outcome:
                        on_outcome(outcome)
                    bar.update(1)
        except BaseException:
            _stop(active)
            raise
    return [outcomes[index] for index in sorted(outcomes)]


@dataclass(frozen=True)
class SlurmOptions:
    """Slurm resources of each array task. ``time_minutes`` is the wall-clock limit per task;
    ``cluster`` is passed to ``submitit.AutoExecutor`` (None = detect, ``"local"`` / ``"debug"`` for
    tests)."""

    partition: str | None = None
    time_minutes: int = 24 * 60
    gpus: int = 0
    cpus: int = 4
    mem_gb: int | None = None
    array_parallelism: int = 64
    cluster: str | None = None


class SlurmTask:
    """The callable submitted per array task; on preemption or timeout submitit calls `checkpoint`,
    which requeues the same task: `run_job` then resumes from the job's newest checkpoint."""

    def __call__(self, job: Job) -> JobOutcome:
        from olatbench.bench.execute import run_job

        return run_job(job, progress=False)

    def checkpoint(self, job: Job):
        from submitit.helpers import DelayedSubmission

        return DelayedSubmission(SlurmTask(), job)


def submit_slurm(jobs: Sequence[Job], out: str | Path, options: SlurmOptions) -> list:
    """Submit the jobs as one job array; returns the submitit jobs (``.job_id``, ``.result()``)."""
    try:
        import submitit
    except ImportError as error:
        raise RuntimeError(
            "the slurm executor needs submitit: pip install 'olatbench[slurm]'"
        ) from error
    executor = submitit.AutoExecutor(folder=Path(out) / ".submitit" / "%j", cluster=options.cluster)
    parameters = {
        "name": "olatbench",
        "timeout_min": options.time_minutes,
        "cpus_per_task": options.cpus,
        "slurm_array_parallelism": options.array_parallelism,
    }
    if options.gpus:
        parameters["gpus_per_node"] = options.gpus
    if options.partition:
        parameters["slurm_partition"] = options.partition
    if options.mem_gb:
        parameters["mem_gb"] = options.mem_gb
    executor.update_parameters(**parameters)
    return executor.map_array(SlurmTask(), list(jobs))


def wait_slurm(
    submitted: list, jobs: Sequence[Job], progress: bool = True, on_outcome: OnOutcome | None = None
) -> list[JobOutcome]:
    """Wait for submitted array tasks; a task that died outside `run_job` is reported as failed."""
    from olatbench.bench.outcome import JobOutcome

    outcomes = []
    with progress_bar(total=len(submitted), desc="jobs", disable=not progress, unit="job") as bar:
        for task, job in zip(submitted, jobs, strict=True):
            try:
                outcome = task.result()
            except Exception as error:
                outcome = JobOutcome(
                    job.id,
                    job.label,
                    job.folder,
                    "failed",
                    error=f"slurm task {task.job_id} failed: {type(error).__name__}: {error}",
                )
            outcomes.append(outcome)
            if on_outcome:
                on_outcome(outcome)
            bar.update(1)
    return outcomes
