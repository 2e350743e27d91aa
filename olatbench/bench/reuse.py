"""Train each experiment once: a job that differs from a finished one only by its variant's name
reuses its model.

A variant name is a label. SSD-GS's ``ablation-D`` (the full composition) and ``schedule-I``
(the default schedule) resolve to the same config as ``default``, so for one scene and seed the
three jobs are the same experiment, which the paper's grids name three times. Two jobs are the same
experiment when their identities (`Job.identity`: method, resolved config, suite, scene, seed,
colour space, resolution, splits, data manifest, protocol, code) are equal in everything but
``variant``; `experiment_key` hashes exactly that.

Before training, `adopt_finished_model` looks for a finished job of the same experiment among the
job's siblings (``<out>/<suite>/<method>/*/<scene>/seed<k>/``). When it finds one, it copies that
job's final checkpoint into the job's folder, stamped with the job's own id
(`olatbench.bench.checkpoints.load_checkpoint` refuses a checkpoint of another job), and its
training log; the runner then resumes at the last step, i.e. evaluates the model as usual. Every
render, metric and hash in the job's folder is computed there; ``results.json`` names the source job
under ``model.reused_from`` and ``timing.train_seconds`` is the source's training time
(what the model cost).

A sibling of the same experiment that is running in another process is waited for when its job id
sorts before this job's (so that of two such jobs started together, one trains and the other waits,
never both waiting); otherwise the job trains itself. Official implementations are never reused
(they cannot resume).
"""

from __future__ import annotations

import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from olatbench.bench.jobs import Job, hash_json
from olatbench.bench.store import (
    DONE_FILE,
    JOB_FILE,
    TRAIN_LOG_FILE,
    is_locked,
    job_lock,
    list_checkpoints,
    read_job_file,
)


def experiment_key(identity: dict[str, Any]) -> str:
    """Hash of a job identity (`Job.identity`, or the ``identity`` of a job.json) without its
    variant name."""
    return hash_json({key: value for key, value in identity.items() if key != "variant"})


def _sibling_folders(job: Job) -> list[Path]:
    """Folders of the same method, suite, scene and seed under other variant names (sorted)."""
    folder = Path(job.folder)
    method_root = folder.parents[2]  # <out>/<suite>/<method>/<variant>/<scene>/seed<k>
    return sorted(
        path
        for path in method_root.glob(f"*/{folder.parent.name}/{folder.name}")
        if path.resolve() != folder.resolve() and (path / JOB_FILE).is_file()
    )


def _is_finished(folder: Path, job_file: dict[str, Any]) -> bool:
    """Whether the job of ``folder`` (its job.json: ``job_file``) is done and its final checkpoint
    is present."""
    done = folder / DONE_FILE
    if not done.is_file() or done.read_text().strip() != job_file.get("id"):
        return False
    checkpoints = list_checkpoints(folder)
    return bool(checkpoints) and checkpoints[-1][0] == job_file["identity"]["config"].get(
        "iterations"
    )


def find_reusable(job: Job, wait: bool = True) -> tuple[Path, str] | None:
    """(folder, job id) of a finished job of the same experiment as ``job``, or None.

    With ``wait``, a sibling of the same experiment that another process is running is waited for
    when its id sorts before ``job.id`` (see the module docstring)."""
    if job.official is not None or not job.id:
        return None
    key = experiment_key(job.identity())
    for folder in _sibling_folders(job):
        data = read_job_file(folder)
        if not data or "identity" not in data or experiment_key(data["identity"]) != key:
            continue
        finished = _is_finished(folder, data)
        if wait and not finished and is_locked(folder) and str(data.get("id")) < job.id:
            # returns once that job's process has let go of its folder
            with job_lock(folder, wait=True):
                finished = _is_finished(folder, data)
        if finished:
            return folder, str(data["id"])
    return None


def adopt_finished_model(job: Job, source: Path, source_id: str) -> Path:
    """Copy ``source``'s final checkpoint into ``job``'s folder under ``job.id``
    (and its training log); returns the new checkpoint's path. The training log is copied only when
    the job has none."""
    import torch

    from olatbench.atomic import atomic_path
    from olatbench.bench.checkpoints import checkpoint_dir, load_checkpoint

    path = list_checkpoints(source)[-1][1]
    payload = load_checkpoint(path, source_id)
    payload["job_id"] = job.id
    target = checkpoint_dir(job.folder) / path.name
    with atomic_path(target) as temporary:
        torch.save(payload, temporary)
    log_source, log_target = source / TRAIN_LOG_FILE, Path(job.folder) / TRAIN_LOG_FILE
    if log_source.is_file() and not log_target.exists():
        with atomic_path(log_target) as temporary:
            shutil.copyfile(log_source, temporary)
    return target


def order_for_reuse(jobs: Sequence[Job]) -> list[Job]:
    """``jobs`` with every job whose experiment an earlier job already covers moved to the end
    (stable), so that parallel executors train each experiment before the jobs that can reuse it
    start."""
    seen: set[str] = set()
    first, later = [], []
    for job in jobs:
        key = experiment_key(job.identity())
        (later if key in seen and job.official is None else first).append(job)
        seen.add(key)
    return first + later


def reuse_notes(jobs: Sequence[Job]) -> list[str | None]:
    """For a dry run: per job, how it will get its model without training (``"reuses <variant>"``
    when a finished sibling is the same experiment, ``"same experiment as #<index>"`` when an
    earlier job of the plan is), else None. Jobs without an id (data not there yet) are matched
    within the plan only."""
    first_index: dict[str, int] = {}
    notes: list[str | None] = []
    for index, job in enumerate(jobs):
        found = find_reusable(job, wait=False)
        key = experiment_key(job.identity())
        if job.official is not None:
            notes.append(None)
        elif found is not None:
            notes.append(f"reuses {found[0].parent.parent.name}")
        elif key in first_index:
            notes.append(f"same experiment as #{first_index[key]}")
        else:
            notes.append(None)
        first_index.setdefault(key, index)
    return notes
