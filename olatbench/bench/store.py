"""The run store: where job folders live and what state each one is in.

Layout: ``<out>/<suite>/<method>/<variant>/<scene>/seed<k>/`` holding ``job.json`` (written when the
job is planned), ``config.json``, ``checkpoints/``, ``renders/<split>/<frame_id>.png``, ``log.txt``,
``train_log.jsonl``, ``results.json`` and, last, ``DONE`` (the job id). A failed job has
``error.txt`` and a ``results.json`` with ``status: "failed"``.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from olatbench.bench.results import ResultsError, read_results
from olatbench.datasets.jsontext import parse_json
from olatbench.names import path_component

JOB_FILE = "job.json"
DONE_FILE = "DONE"
RESULTS_FILE = "results.json"
ERROR_FILE = "error.txt"
TRAIN_LOG_FILE = "train_log.jsonl"
LOCK_FILE = ".lock"
OFFICIAL_DIR = "official"  # an official implementation's working folder (olatbench.bench.official)
_CHECKPOINT_NAME = re.compile(r"^step_(\d+)\.pt$")


def job_folder(
    out: str | Path, suite: str, method: str, variant: str, scene: str, seed: int
) -> Path:
    """The folder of one job below the output root; a `ValueError` when a name cannot be one folder
    of it (`olatbench.names.path_component`: empty, ``..``, a separator, ...), so no job is written
    outside ``out`` or where another name's folder belongs."""
    for what, name in (
        ("suite", suite),
        ("method", method),
        ("variant", variant),
        ("scene", scene),
    ):
        path_component(name, what)
    return Path(out) / suite / method / variant / scene / f"seed{seed}"


def checkpoint_dir(folder: str | Path) -> Path:
    """``<job folder>/checkpoints`` (files ``step_<N>.pt``, written by
    `olatbench.bench.checkpoints`)."""
    return Path(folder) / "checkpoints"


def list_checkpoints(folder: str | Path) -> list[tuple[int, Path]]:
    """(step, path) of every checkpoint of a job folder, oldest first."""
    directory = checkpoint_dir(folder)
    if not directory.is_dir():
        return []
    found = [
        (int(match.group(1)), path)
        for path in directory.iterdir()
        if (match := _CHECKPOINT_NAME.match(path.name))
    ]
    return sorted(found)


def find_results(runs_root: str | Path) -> list[Path]:
    """Every results.json below ``runs_root`` (sorted)."""
    return sorted(Path(runs_root).rglob(RESULTS_FILE))


@dataclass(frozen=True)
class JobState:
    """State of one job folder.

    ``state``: ``done`` (DONE matches the job id and results.json is a readable record of that
    finished job), ``running`` (another process holds the job's lock), ``failed``, ``partial``
    (checkpoint at ``step`` of ``iterations``; for official code: started, not finished, and rerun
    from the start), ``pending`` (planned, nothing trained yet), ``stale`` (the folder holds another
    job id than the one asked for), ``damaged`` (its job.json, or the results.json of a job marked
    done, cannot be read: ``message`` says which and how to repair it; ``olatbench run`` sets the
    damaged files aside (`set_aside_damaged`) and reruns the job, re-evaluating its final
    checkpoint) or ``absent``.
    """

    folder: Path
    state: str
    job_id: str | None = None
    step: int | None = None
    iterations: int | None = None
    message: str = ""
    # what the run's health checks found (olatbench.bench.health), first of each kind
    warnings: tuple[str, ...] = ()


REPAIR_HINT = (
    "rerun the 'olatbench run' command that made it: it keeps the damaged file as <name>.damaged "
    "and re-evaluates the job from its final checkpoint (or retrains it if there is none)"
)


def read_job_file(folder: str | Path) -> dict[str, Any] | None:
    """The job.json of a folder, or None when there is none (or it is unreadable)."""
    try:
        return job_record(folder)
    except ValueError:
        return None


def job_record(folder: str | Path) -> dict[str, Any] | None:
    """The job.json of a folder, None when there is none; a `ValueError` naming the file when it is
    unreadable (truncated, not JSON, not an object)."""
    path = Path(folder) / JOB_FILE
    try:
        data = parse_json(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None
    # not UTF-8, malformed, nested too deep, an integer too long
    except (OSError, ValueError) as error:
        raise ValueError(f"{path} is unreadable ({error})") from None
    if not isinstance(data, dict) or not isinstance(data.get("id", ""), str):
        raise ValueError(f"{path} is not a job (expected a JSON object with an id)")
    return data


def _results_problem(folder: Path, job_id: str) -> str | None:
    """Why the results.json of a job marked done does not record that finished job
    (None: it does)."""
    path = folder / RESULTS_FILE
    try:
        results = read_results(path)
    except ResultsError as error:
        return f"marked done, but {error}"
    recorded = (results.get("job") or {}).get("id")
    if results["status"] != "done" or recorded != job_id:
        return f"marked done, but {path} records {results['status']} job {recorded}"
    return None


DAMAGED_SUFFIX = ".damaged"


def set_aside_damaged(folder: str | Path, job_id: str) -> list[tuple[Path, str]]:
    """Before job ``job_id`` runs in ``folder``: rename its job.json when unreadable, and its
    results.json when DONE marks the job finished but that file does not record it (the files
    `job_state` calls ``damaged``), to ``<name>.damaged`` (``.damaged-2``, … when taken), so the
    rerun that repairs the job overwrites nothing a user edited. Returns each new path with what was
    wrong (reports and `status` read neither name). Reads no lock, so it also works under the job's
    own."""
    folder = Path(folder)
    damaged: list[tuple[str, str]] = []
    try:
        job_record(folder)
    except ValueError as error:
        damaged.append((JOB_FILE, str(error)))
    done = folder / DONE_FILE
    if done.is_file() and done.read_text(errors="replace").strip() == job_id:
        problem = _results_problem(folder, job_id)
        if problem is not None and (folder / RESULTS_FILE).is_file():
            damaged.append((RESULTS_FILE, problem))
    kept = []
    for name, problem in damaged:
        path = folder / name
        target, number = path.with_name(name + DAMAGED_SUFFIX), 1
        while target.exists():
            number += 1
            target = path.with_name(f"{name}{DAMAGED_SUFFIX}-{number}")
        path.rename(target)
        kept.append((target, problem))
    return kept


def holds_finished_job(folder: str | Path) -> bool:
    """Whether ``folder`` holds a job that finished by its own record
    (job.json, DONE, results.json), whatever job a new plan asks for there."""
    return job_state(folder).state == "done"


def in_suite(folder: str | Path, suite: str | None) -> bool:
    """Whether the job in ``folder`` belongs to ``suite`` (by its job.json; every job for None)."""
    if suite is None:
        return True
    job = read_job_file(folder)
    return job is not None and job.get("suite") == suite


def job_state(folder: str | Path, expected_id: str | None = None) -> JobState:
    """The state of the job folder; ``expected_id`` (from a new plan) turns a mismatch into
    ``stale``."""
    folder = Path(folder)
    if not folder.is_dir():
        return JobState(folder, "absent")
    checkpoints = list_checkpoints(folder)
    step = checkpoints[-1][0] if checkpoints else None
    try:
        job = job_record(folder)
    except ValueError as error:
        if is_locked(folder):
            return JobState(folder, "running", step=step)
        return JobState(folder, "damaged", step=step, message=f"{error}; {REPAIR_HINT}")
    job_id = job.get("id") if job else None
    iterations = job.get("config", {}).get("iterations") if job else None
    if expected_id is not None and job_id is not None and job_id != expected_id:
        return JobState(
            folder,
            "stale",
            job_id,
            iterations=iterations,
            message=f"holds job {job_id}, the plan asks for {expected_id}",
        )
    done = folder / DONE_FILE
    if done.is_file() and job_id is not None and done.read_text(errors="replace").strip() == job_id:
        problem = _results_problem(folder, job_id)
        if problem is None:
            return JobState(folder, "done", job_id, step=iterations, iterations=iterations)
        if not is_locked(folder):
            return JobState(
                folder,
                "damaged",
                job_id,
                step=step,
                iterations=iterations,
                message=f"{problem}; {REPAIR_HINT}",
            )
    if is_locked(folder):
        return JobState(folder, "running", job_id, step=step, iterations=iterations)
    if (folder / ERROR_FILE).is_file():
        first_line = _last_line(folder / ERROR_FILE)
        return JobState(
            folder, "failed", job_id, step=step, iterations=iterations, message=first_line
        )
    if step is not None:
        return JobState(folder, "partial", job_id, step=step, iterations=iterations)
    if job and job.get("official") is not None and (folder / OFFICIAL_DIR).is_dir():
        return JobState(
            folder,
            "partial",
            job_id,
            iterations=iterations,
            message=(
                "interrupted; official scripts cannot resume: the next run restarts its commands"
            ),
        )
    return JobState(folder, "pending", job_id, iterations=iterations)


def _last_line(path: Path) -> str:
    lines = [
        line
        for line in path.read_text(encoding="utf-8", errors="replace").splitlines()
        if line.strip()
    ]
    return lines[-1].strip() if lines else ""


def scan_runs(runs_root: str | Path) -> list[JobState]:
    """The state of every job folder (a folder with job.json) below ``runs_root``, with the warnings
    its training recorded."""
    from olatbench.bench.health import read_warnings

    return [
        replace(state, warnings=tuple(read_warnings(state.folder)))
        for state in (job_state(path.parent) for path in sorted(Path(runs_root).rglob(JOB_FILE)))
    ]


@contextmanager
def job_lock(folder: str | Path, wait: bool = False) -> Iterator[bool]:
    """Hold an exclusive advisory lock (``flock``) on the job folder; yields False when another
    process holds it, or with ``wait`` blocks until it is released and then yields True. The kernel
    releases it when the process dies (even by SIGKILL), so no lock goes stale. Without ``fcntl``
    (Windows) this always yields True."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - non-POSIX
        yield True
        return
    path = Path(folder) / LOCK_FILE
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX if wait else fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            yield False
            return
        try:
            yield True
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def is_locked(folder: str | Path) -> bool:
    """True when another process is running the job in ``folder`` (holds its lock).

    Only reads: the lock file is opened read-only and probed with a shared lock (which the runner's
    exclusive one blocks; a read lock needs no write access, also where ``flock`` is emulated by
    byte-range locks), so the state of a read-only run folder (a mounted archive, another user's
    results) can be inspected.
    """
    path = Path(folder) / LOCK_FILE
    try:
        import fcntl
    except ImportError:  # pragma: no cover - non-POSIX
        return False
    try:
        handle = open(path, "rb")  # noqa: SIM115 - closed below
    except OSError:  # absent (never run) or unreadable: nobody can hold it through this file
        return False
    with handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        fcntl.flock(handle, fcntl.LOCK_UN)
        return False
