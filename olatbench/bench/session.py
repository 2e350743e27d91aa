"""The run session: what ``olatbench run`` does between planning and printing, as library calls.

Given planned jobs (`olatbench.bench.plan.make_plan`), a session decides each job's fate from its
folder (`triage`: skip a finished job, leave a running one to its process, keep or replace a stale
one, run the rest), prepares the folders (`prepare`: checks they are writable, removes the folders
it replaces, writes each pending job.json so that ``olatbench status`` lists it, orders the jobs for
model reuse), runs them on an executor (`execute`) and sums the outcomes up as one exit code
(`RunSummary.exit_code`). A notebook gets what the command line gets::

    from olatbench.bench.plan import make_plan
    from olatbench.bench.session import run_plan
    from olatbench.datasets.suites import get_suite

    summary = run_plan(make_plan("ssdgs", get_suite("mini"), "runs"), "runs")
    summary.exit_code      # 0: every job done; 1: a job failed; 3: jobs left to another process

Nothing here prints: the command line prints from the returned records and the ``on_outcome``
callback.
"""

from __future__ import annotations

import errno
import os
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from olatbench.atomic import WriteError, write_json
from olatbench.bench.executors import EXECUTORS, OnOutcome, SlurmOptions
from olatbench.bench.jobs import Job
from olatbench.bench.store import JOB_FILE, JobState, holds_finished_job, job_state

if TYPE_CHECKING:  # the job runner imports torch: loaded when a job runs
    from olatbench.bench.outcome import JobOutcome

#: ``olatbench run``'s exit codes (docs/guarantees.md); 2 is click's usage error.
EXIT_DONE, EXIT_FAILED, EXIT_USAGE, EXIT_RUNNING_ELSEWHERE = 0, 1, 2, 3
EXIT_INTERRUPTED, EXIT_TERMINATED = 130, 143  # 128 + SIGINT, 128 + SIGTERM: the shells' convention


class StaleFoldersError(Exception):
    """Job folders hold results of another job (config, data or code changed) and neither ``force``
    nor ``keep_finished`` says what to do with them; ``states`` are their states."""

    def __init__(self, states: Sequence[JobState]) -> None:
        listing = "\n  ".join(f"{state.folder}: {state.message}" for state in states[:10])
        super().__init__(
            f"{len(states)} job folder(s) hold results of a different job (config, data or code "
            f"changed):\n  {listing}\nRerun with --keep-finished to replace only the unfinished "
            "ones (finished jobs stay as they are), with --force to replace them all, or choose "
            "another --output"
        )
        self.states = list(states)


@dataclass(frozen=True)
class Triage:
    """Each planned job's fate, from its folder's state: ``to_run`` (in plan order), ``skipped``
    (finished), ``running`` (locked by another process), ``kept`` (finished under other inputs, kept
    by ``keep_finished``); ``replaced``: the folders of ``to_run`` that hold another job and are
    removed before it runs; ``damaged``: how many of ``to_run`` are finished jobs with a damaged
    record (re-evaluated, the damaged files set aside)."""

    to_run: list[Job]
    skipped: list[Job]
    running: list[Job]
    kept: list[Job]
    replaced: frozenset[str]
    damaged: int


def job_states(jobs: Sequence[Job]) -> list[JobState]:
    """The state of each job's folder, judged against the job's own id."""
    return [job_state(job.folder, job.id or None) for job in jobs]


def triage(
    jobs: Sequence[Job],
    states: Sequence[JobState],
    force: bool = False,
    keep_finished: bool = False,
) -> Triage:
    """Decide each job's fate (`Triage`); `StaleFoldersError` when folders hold other jobs and
    neither ``force`` (replace them all, and rerun finished jobs) nor ``keep_finished`` (keep the
    finished ones, replace the rest) is given."""
    stale = [state for state in states if state.state == "stale"]
    if stale and not (force or keep_finished):
        raise StaleFoldersError(stale)
    to_run, skipped, running, kept = [], [], [], []
    for job, state in zip(jobs, states, strict=True):
        if state.state == "done" and not force:
            skipped.append(job)
        elif (
            state.state == "stale"
            and keep_finished
            and not force
            and holds_finished_job(job.folder)
        ):
            kept.append(job)
        elif state.state == "running":
            running.append(job)
        else:
            to_run.append(job)
    replaced = frozenset(
        job.folder
        for job, state in zip(jobs, states, strict=True)
        if state.state == "stale" or (force and state.state != "running")
    )
    damaged = sum(state.state == "damaged" for state in states)
    return Triage(to_run, skipped, running, kept, replaced, damaged)


def prepare(decided: Triage, reuse: bool = True) -> list[Job]:
    """Make the folders of ``decided.to_run`` ready and return the jobs in the order to run them
    (models to reuse first, `olatbench.bench.reuse.order_for_reuse`, unless ``reuse`` is False). A
    `WriteError` (an `OSError`) names the first folder this process cannot write, before anything is
    removed or run."""
    from olatbench.bench.reuse import order_for_reuse

    _check_writable(decided.to_run)
    for job in decided.to_run:
        if job.folder in decided.replaced and Path(job.folder).exists():
            shutil.rmtree(job.folder)
    write_pending(decided.to_run)
    return order_for_reuse(decided.to_run) if reuse else list(decided.to_run)


def write_pending(jobs: Sequence[Job]) -> None:
    """Write job.json into each folder to run that has none, so `olatbench status` lists it before
    it starts."""
    for job in jobs:
        path = Path(job.folder) / JOB_FILE
        if not path.is_file():
            write_json(path, job.to_json())


def _check_writable(jobs: Sequence[Job]) -> None:
    """A `WriteError` naming the first job folder (or its nearest existing parent) this process
    cannot write: a read-only file system or missing permission stops the run before any job
    starts."""
    for job in jobs:
        path = Path(job.folder)
        while not path.exists() and path != path.parent:
            path = path.parent
        if not os.access(path, os.W_OK):
            read_only = bool(os.statvfs(path).f_flag & os.ST_RDONLY)
            code = errno.EROFS if read_only else errno.EACCES
            raise WriteError(path, OSError(code, os.strerror(code)))


@dataclass(frozen=True)
class Executor:
    """Where the jobs run: ``name`` one of `EXECUTORS`; ``workers`` processes for ``local``;
    ``slurm`` the array's resources and ``wait`` whether to wait for the array
    (False: return once submitted)."""

    name: str = "inline"
    workers: int = 1
    slurm: SlurmOptions = field(default_factory=SlurmOptions)
    wait: bool = True

    def __post_init__(self) -> None:
        if self.name not in EXECUTORS:
            raise ValueError(f"unknown executor {self.name!r}; one of {', '.join(EXECUTORS)}")


@dataclass(frozen=True)
class RunSummary:
    """What a session did: ``outcomes`` of the jobs it ran (empty when nothing was left to run, or
    when Slurm tasks were submitted without waiting: ``submitted`` then holds the submitit jobs),
    ``running``: how many planned jobs were left to another process."""

    outcomes: list[JobOutcome]
    running: int
    submitted: list = field(default_factory=list)

    @property
    def failed(self) -> int:
        return sum(outcome.status == "failed" for outcome in self.outcomes)

    @property
    def elsewhere(self) -> int:
        """Jobs left to another process: planned as running, or locked when their turn came."""
        return self.running + sum(outcome.status == "skipped" for outcome in self.outcomes)

    @property
    def exit_code(self) -> int:
        """`EXIT_FAILED` when a job failed, else `EXIT_RUNNING_ELSEWHERE` when jobs were left to
        another process, else `EXIT_DONE` (every job of the plan is done, or the Slurm array was
        submitted)."""
        if self.failed:
            return EXIT_FAILED
        return EXIT_RUNNING_ELSEWHERE if self.elsewhere else EXIT_DONE


def execute(
    jobs: Sequence[Job],
    out: str | Path,
    executor: Executor = Executor(),
    progress: bool = True,
    on_outcome: OnOutcome | None = None,
    on_submitted: Callable[[list], None] | None = None,
) -> tuple[list[JobOutcome], list]:
    """Run prepared jobs on ``executor``: (outcomes, submitted Slurm tasks). ``out`` is the plan's
    output folder (Slurm's logs go to ``out/.submitit``); ``on_outcome`` is called as each job ends,
    ``on_submitted`` once a Slurm array is submitted. Ctrl-C (or SIGTERM to the local executor,
    `olatbench.bench.executors.Terminated`) propagates as `KeyboardInterrupt`; the jobs resume on
    the next run."""
    from olatbench.bench import executors

    if executor.name == "slurm":
        submitted = executors.submit_slurm(jobs, out, executor.slurm)
        if on_submitted:
            on_submitted(submitted)
        if not executor.wait:
            return [], submitted
        return executors.wait_slurm(submitted, jobs, progress, on_outcome), submitted
    if executor.name == "local":
        return executors.run_local(jobs, executor.workers, progress, on_outcome), []
    return executors.run_inline(jobs, progress, on_outcome), []


def run_plan(
    jobs: Sequence[Job],
    out: str | Path,
    executor: Executor = Executor(),
    force: bool = False,
    keep_finished: bool = False,
    reuse: bool = True,
    progress: bool = True,
    on_outcome: OnOutcome | None = None,
) -> RunSummary:
    """Everything ``olatbench run`` does after planning the jobs into ``out``: `triage`, `prepare`,
    `execute`. Raises `StaleFoldersError` (nothing done) and `WriteError` (nothing run) as the
    command line reports them."""
    decided = triage(jobs, job_states(jobs), force=force, keep_finished=keep_finished)
    ordered = prepare(decided, reuse=reuse)
    if not ordered:
        return RunSummary([], len(decided.running))
    outcomes, submitted = execute(ordered, out, executor, progress, on_outcome)
    return RunSummary(outcomes, len(decided.running), submitted)
