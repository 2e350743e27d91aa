"""Rebuild a trained method from its job folder: the one restore path of the runner, sweeps and the
viewer.

`restore` reads ``job.json`` (`Job.from_json`), checks ``config.json`` against it, finds the final
checkpoint (the one at ``job.iterations``; with ``partial=True`` the newest one, of a job still
training), imports the method from the job's ``method_ref``, sets it up on the job's training views
and loads the checkpoint's state. The views carry cameras, lights and frame ids in training order;
their images are read only when the method declares it needs them (`Method.restore_needs_images`;
the Gaussian methods do not), so rendering a trained model reads no training image. `load_state`
loads a checkpoint into a set-up method (`load_checkpoint` checks the file, as the runner's resume
does).

Every problem with the folder is one `RestoreError` whose message names the file, raised before
anything expensive (scene loading, set-up) happens where the check allows it.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from olatbench.bench.checkpoints import load_checkpoint
from olatbench.bench.jobs import Job
from olatbench.bench.plan import load_method_class
from olatbench.bench.store import JOB_FILE, job_record, list_checkpoints
from olatbench.bench.views import frame_views, load_views
from olatbench.datasets.jsontext import parse_json

if TYPE_CHECKING:
    from olatbench.methods.base import Method

CONFIG_FILE = "config.json"


class RestoreError(ValueError):
    """A job folder from which no trained method can be rebuilt; the message names the file and the
    fix."""


class NotAJobFolderError(RestoreError):
    """A folder without a ``job.json``: the wrong folder was given (a usage error for the commands
    that take a job folder)."""


def read_job(folder: str | Path) -> Job:
    """The `Job` of a job folder's ``job.json`` (read by `olatbench.bench.store.job_record`): a
    `NotAJobFolderError` when there is none, a `RestoreError` when it is unreadable or not a job."""
    path = Path(folder) / JOB_FILE
    try:
        data = job_record(folder)
    # not UTF-8, malformed, nested too deep, an integer too long, not an object
    except ValueError as error:
        raise RestoreError(str(error)) from None
    if data is None:
        raise NotAJobFolderError(
            f"{path}: not found; is {folder} a job folder "
            "(<out>/<suite>/<method>/<variant>/<scene>/seed<k>)?"
        )
    try:
        return Job.from_json(data)
    except (TypeError, ValueError) as error:
        raise RestoreError(f"{path}: {error}") from None


def newest_checkpoint(folder: str | Path) -> tuple[int, Path]:
    """(step, path) of the job folder's newest checkpoint (a `RestoreError` when there is none
    yet)."""
    checkpoints = list_checkpoints(folder)
    if not checkpoints:
        raise RestoreError(
            f"{Path(folder) / 'checkpoints'}: no checkpoint; the job has not been trained "
            f"(olatbench run ...)"
        )
    return checkpoints[-1]


def final_checkpoint(folder: str | Path, job: Job) -> Path:
    """The checkpoint written at the job's last step (a `RestoreError` naming the newest step
    otherwise)."""
    step, path = newest_checkpoint(folder)
    if step != job.iterations:
        raise RestoreError(
            f"{path}: the newest checkpoint is at step {step} of {job.iterations}; the job is not "
            f"finished (rerun 'olatbench run' with the same options to resume it)"
        )
    return path


def method_class(job: Job, folder: str | Path = "") -> type[Method]:
    """The job's `Method` class, imported from ``method_ref`` (a `RestoreError` listing the known
    methods)."""
    try:
        found = load_method_class(job)
    except (ImportError, AttributeError, ValueError) as error:
        from olatbench.methods.registry import method_names

        raise RestoreError(
            f"{Path(folder) / JOB_FILE}: method '{job.method}' ({job.method_ref}) cannot be "
            f"imported ({error}); known methods: {', '.join(method_names())}. Is its plugin "
            f"installed?"
        ) from None
    from olatbench.methods.base import Method

    if not (isinstance(found, type) and issubclass(found, Method)):
        raise RestoreError(
            f"{Path(folder) / JOB_FILE}: {job.method_ref} is not an olatbench Method"
        )
    return found


def method_config(job: Job, cls: type[Method], folder: str | Path = "") -> Any:
    """The config of ``cls`` built from job.json's ``config`` (a `RestoreError` naming the file and
    the field when the config is not one of that method's, e.g. a job.json whose ``method`` was
    changed by hand)."""
    try:
        return cls.resolve_config(None, **job.config)
    except (TypeError, ValueError) as error:
        raise RestoreError(
            f"{Path(folder) / JOB_FILE}: config: not a config of method '{job.method}' ({error})"
        ) from None


def load_state(method: Method, path: str | Path, job_id: str) -> dict[str, Any]:
    """Load checkpoint ``path`` of job ``job_id`` into ``method`` (already set up on the job's
    training views); returns the whole payload (``step``, ``rng``, ``train_seconds``, …) for a
    resume."""
    payload = load_checkpoint(path, job_id)
    method.load_state_dict(payload["method"])
    return payload


def restore(
    job_folder: str | Path,
    device: str = "cpu",
    *,
    train_images: bool = False,
    progress: bool = False,
    checkpoint: str | Path | None = None,
) -> tuple[Method, Job]:
    """The trained method of a finished job and its `Job` (``device`` and ``folder`` set to the
    given ones).

    Reads ``job.json``, ``config.json`` (must equal the job's config), the final checkpoint (or
    ``checkpoint``, one of the job's own, e.g. the newest of a job still training:
    `newest_checkpoint`) and the scene's frame records; the training images only if the method's
    `Method.restore_needs_images` says so or the caller asks for them (``train_images``: to take
    further training steps, e.g. a benchmark).
    """
    from olatbench.datasets import load_scene
    from olatbench.datasets.errors import DatasetError

    folder = Path(job_folder)
    job, final, cls = check_job(folder, device, partial=checkpoint is not None)
    checkpoint = final if checkpoint is None else Path(checkpoint)
    try:
        scene = load_scene(job.scene_path, format=job.scene_format)
        frames = scene.split(job.train_split)
    except (DatasetError, OSError, KeyError, ValueError) as error:
        raise RestoreError(
            f"{folder / JOB_FILE}: cannot read the scene {job.scene_path} ({error})"
        ) from None
    needs_images = train_images or cls.restore_needs_images
    views = load_views(frames, job, progress, 0) if needs_images else frame_views(frames, job)
    method = cls(method_config(job, cls, folder))
    method.setup(views, device, job.seed)
    try:
        load_state(method, checkpoint, job.id)
    except (RuntimeError, ValueError, KeyError) as error:
        raise RestoreError(f"{checkpoint}: {error}") from None
    return method, job


def check_job(
    job_folder: str | Path, device: str = "cpu", *, partial: bool = False
) -> tuple[Job, Path, type[Method]]:
    """The cheap checks of `restore`, before any scene or model is loaded: (job with ``device`` and
    ``folder`` set, final checkpoint — with ``partial``, the newest, of a job still training —,
    method class); a `RestoreError` says what is wrong."""
    folder = Path(job_folder)
    job = replace(read_job(folder), device=device, folder=str(folder))
    config_path = folder / CONFIG_FILE
    try:
        config = parse_json(config_path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RestoreError(
            f"{config_path}: not found (the runner writes it beside job.json)"
        ) from None
    except (OSError, ValueError) as error:
        raise RestoreError(f"{config_path}: unreadable ({error})") from None
    if config != job.config:
        raise RestoreError(
            f"{config_path}: differs from the config in job.json; the checkpoint was trained with "
            f"job.json's"
        )
    checkpoint = newest_checkpoint(folder)[1] if partial else final_checkpoint(folder, job)
    cls = method_class(job, folder)
    method_config(job, cls, folder)
    return job, checkpoint, cls
