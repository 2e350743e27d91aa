"""Which job folders a ``olatbench view FOLDER`` serves: the folder itself when it is a job, else
every job below it (a run folder) with at least one checkpoint — finished, or still training (the
viewer follows its newest checkpoint) —, each checked cheaply (`olatbench.bench.restore.check_job`)
before any server starts."""

from __future__ import annotations

from pathlib import Path

from olatbench.bench.restore import RestoreError, check_job
from olatbench.bench.store import JOB_FILE


class NoJobFolder(RestoreError):
    """The folder given holds no job folder at all (no job.json in or below it): a usage error of
    the command."""


def job_folders(folder: str | Path, device: str = "cpu") -> tuple[list[Path], list[str]]:
    """(job folders to serve, one line per job folder skipped and why).

    A job folder must be restorable (a `RestoreError` otherwise); a run folder must hold at least
    one restorable job (the error then names why each one is not); a folder with no job.json in or
    below it is a `NoJobFolder`.
    """
    folder = Path(folder)
    if (folder / JOB_FILE).is_file():
        check_job(folder, device, partial=True)
        return [folder], []
    candidates = sorted(path.parent for path in folder.rglob(JOB_FILE))
    if not candidates:
        raise NoJobFolder(
            f"{folder}: no job.json in or below it; pass a job folder "
            "(<out>/<suite>/<method>/<variant>/<scene>/seed<k>) or a run folder holding some"
        )
    found, skipped = [], []
    for candidate in candidates:
        try:
            check_job(candidate, device, partial=True)
        except RestoreError as error:
            skipped.append(str(error))
        else:
            found.append(candidate)
    if not found:
        raise RestoreError(
            f"{folder}: none of its {len(candidates)} job folders can be shown:\n  "
            + "\n  ".join(skipped)
        )
    return found, skipped
