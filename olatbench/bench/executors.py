"""Executors: run a list of jobs inline, in a local process pool, or as one Slurm job array (submitit).

Every executor calls `olatbench.bench.execute.run_job`, which records failures in the job folder
instead of raising, so one failing job never stops the others.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from olatbench.bench.jobs import Job
from olatbench.progress import progress_bar

if TYPE_CHECKING:  # the job runner imports torch: loaded when a job runs, not when the CLI lists executors
    from olatbench.bench.outcome import JobOutcome

EXECUTORS = ("inline", "local", "slurm")
OnOutcome = Callable[["JobOutcome"], None]


def run_inline(jobs: Sequence[Job], progress: bool = True, on_outcome: OnOutcome | None = None) -> list[JobOutcome]:
    """Run the jobs one after another in this process."""
    from olatbench.bench.execute import run_job

    outcomes = []
    with progress_bar(total=len(jobs), desc="jobs", position=0, disable=not progress, unit="job") as bar:
        for job in jobs:
            bar.set_postfix_str(job.label)
            outcome = run_job(job, progress=progress, position=1)
            outcomes.append(outcome)
            if on_outcome:
                on_outcome(outcome)
            bar.update(1)
    return outcomes


def _worker(job: Job, slots, progress: bool, threads: int) -> JobOutcome:
    """Run one job in a pool process; ``slots`` hands out the tqdm row of the per-job bar."""
    import torch

    from olatbench.bench.execute import run_job

    torch.set_num_threads(threads)
    slot = slots.get()
    try:
        return run_job(job, progress=progress, position=slot)
    finally:
        slots.put(slot)


def run_local(jobs: Sequence[Job], workers: int, progress: bool = True, on_outcome: OnOutcome | None = None
              ) -> list[JobOutcome]:
    """Run the jobs in ``workers`` spawned processes, a fresh one per job on Python ≥ 3.11 (honest peak
    memory, isolation from crashes); torch threads are shared out between the workers."""
    from olatbench.bench.outcome import JobOutcome

    context = multiprocessing.get_context("spawn")
    threads = max(1, (os.cpu_count() or 1) // workers)
    outcomes: dict[int, JobOutcome] = {}
    with context.Manager() as manager:
        slots = manager.Queue()
        for slot in range(1, workers + 1):
            slots.put(slot)
        fresh = {"max_tasks_per_child": 1} if sys.version_info >= (3, 11) else {}
        with ProcessPoolExecutor(max_workers=workers, mp_context=context, **fresh) as pool, \
                progress_bar(total=len(jobs), desc="jobs", position=0, disable=not progress, unit="job") as bar:
            futures = {pool.submit(_worker, job, slots, progress, threads): index for index, job in enumerate(jobs)}
            try:
                for future in as_completed(futures):
                    index = futures[future]
                    try:
                        outcome = future.result()
                    except Exception as error:  # the worker process died (segfault, OOM kill)
                        job = jobs[index]
                        outcome = JobOutcome(job.id, job.label, job.folder, "failed",
                                             error=f"worker process died: {type(error).__name__}: {error}")
                    outcomes[index] = outcome
                    if on_outcome:
                        on_outcome(outcome)
                    bar.update(1)
            except KeyboardInterrupt:
                pool.shutdown(wait=False, cancel_futures=True)
                raise
    return [outcomes[index] for index in sorted(outcomes)]


@dataclass(frozen=True)
class SlurmOptions:
    """Slurm resources of each array task. ``time_minutes`` is the wall-clock limit per task;
    ``cluster`` is passed to ``submitit.AutoExecutor`` (None = detect, ``"local"`` / ``"debug"`` for tests)."""

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
        raise RuntimeError("the slurm executor needs submitit: pip install 'olatbench[slurm]'") from error
    executor = submitit.AutoExecutor(folder=Path(out) / ".submitit" / "%j", cluster=options.cluster)
    parameters = {"name": "olatbench", "timeout_min": options.time_minutes, "cpus_per_task": options.cpus,
                  "slurm_array_parallelism": options.array_parallelism}
    if options.gpus:
        parameters["gpus_per_node"] = options.gpus
    if options.partition:
        parameters["slurm_partition"] = options.partition
    if options.mem_gb:
        parameters["mem_gb"] = options.mem_gb
    executor.update_parameters(**parameters)
    return executor.map_array(SlurmTask(), list(jobs))


def wait_slurm(submitted: list, jobs: Sequence[Job], progress: bool = True, on_outcome: OnOutcome | None = None
               ) -> list[JobOutcome]:
    """Wait for submitted array tasks; a task that died outside `run_job` is reported as failed."""
    from olatbench.bench.outcome import JobOutcome

    outcomes = []
    with progress_bar(total=len(submitted), desc="jobs", disable=not progress, unit="job") as bar:
        for task, job in zip(submitted, jobs, strict=True):
            try:
                outcome = task.result()
            except Exception as error:
                outcome = JobOutcome(job.id, job.label, job.folder, "failed",
                                     error=f"slurm task {task.job_id} failed: {type(error).__name__}: {error}")
            outcomes.append(outcome)
            if on_outcome:
                on_outcome(outcome)
            bar.update(1)
    return outcomes
