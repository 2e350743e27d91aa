"""Run one job of an official implementation: the runner's counterpart of the in-process training
loop.

In the job folder: ``job.json`` and ``config.json`` first; ``official/`` (the converted scene and
the official scripts' outputs; the scripts cannot resume a command, so an interrupted job reruns the
commands that had not finished: `olatbench.methods.official.runner`); every command's output
appended to ``log.txt``; the test renders copied to ``renders/<test split>/<frame id>.png`` (8-bit
sRGB, as every method's); ``results.json`` scored under the suite's protocol with
``method_kind: "official"`` and an ``official`` block (repository, pinned and checked-out commit,
launcher, command lines with exit codes and wall times); ``DONE`` last. A failing command leaves
``error.txt`` (the log's last lines, then one line with the step and exit code) and a failed
``results.json``.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.atomic import write_json, write_text
from olatbench.bench.jobs import Job
from olatbench.bench.outcome import (
    JobLog,
    JobOutcome,
    base_results,
    ground_truth,
    mean_scores,
    save_render,
    score_image,
    scored_files,
)
from olatbench.bench.results import write_results
from olatbench.bench.store import DONE_FILE, ERROR_FILE, JOB_FILE, OFFICIAL_DIR, RESULTS_FILE
from olatbench.datasets import colour, load_scene
from olatbench.datasets.records import Frame
from olatbench.methods.official.code import OfficialCode, OfficialConfig
from olatbench.methods.official.process import OfficialRunError
from olatbench.methods.official.runner import OfficialRun, collect, execute, prepare
from olatbench.methods.official.settings import CodeSettings, checkout_commit
from olatbench.methods.registry import get_spec
from olatbench.methods.spec import import_reference
from olatbench.metrics.evaluate import read_prediction


def run_official_job(job: Job, folder: Path, log: JobLog, started: str) -> JobOutcome:
    """Convert, run the official commands, score their renders, write results (module docstring);
    ``started``: the UTC time the job started (results.json ``timing.started``)."""
    for stale in (ERROR_FILE, RESULTS_FILE, DONE_FILE):
        (folder / stale).unlink(missing_ok=True)
    write_json(folder / JOB_FILE, job.to_json())
    write_json(folder / "config.json", job.config)
    code: OfficialCode = import_reference(job.method_ref)
    settings = CodeSettings.from_json(job.official or {"method": job.method})
    # the one resolver
    config: OfficialConfig = get_spec(job.method).resolve_config(None, **job.config)
    log(
        f"job {job.id}: {job.method} (official code) on {job.suite}/{job.label}, "
        f"{config.iterations} iterations; official scripts cannot resume: commands that had not "
        "finished run from their start"
    )
    scene = load_scene(job.scene_path, format=job.scene_format)
    run: OfficialRun | None = None
    try:
        run = prepare(
            code,
            settings,
            scene,
            folder / OFFICIAL_DIR,
            job.suite,
            job.train_split,
            job.test_split,
            tuple(job.resolution) if job.resolution else None,
            config,
            job.seed,
        )
        log(f"scene written as {code.data_format(job.suite)} to {run.scene_dir}")
        _share_threads(run)
        execute(run, log.path)
        metrics = {
            job.test_split: _score(
                job, scene.split(job.test_split), collect(run), run.colourspace, folder
            )
        }
    except OfficialRunError as error:
        return _failed(job, folder, log, error, run, started)
    # a copy of the data; the official outputs stay in model/
    shutil.rmtree(run.scene_dir, ignore_errors=True)
    results = base_results(job, "done", started)
    results["metrics"] = metrics
    results["files"] = {
        job.test_split: scored_files(scene.split(job.test_split), folder, job.test_split)
    }
    train_seconds = sum(r.seconds or 0.0 for r in run.commands if r.step in code.train_steps)
    results["timing"].update(train_seconds=round(train_seconds, 3), render_fps=None)
    results.update(_provenance(job, run, settings))
    # the authors' code fitted the test views' poses
    if code.fits_test_views(job.suite, config.render_args):
        results["evaluation"]["test_pose_fitting"] = {
            "mode": "official",
            "split": job.test_split,
            "frames": {},
        }
    write_results(folder / RESULTS_FILE, results)
    write_text(folder / DONE_FILE, job.id + "\n")
    mean = metrics[job.test_split]["mean"]
    log(f"{job.test_split}: " + ", ".join(f"{k} {v:.4f}" for k, v in mean.items() if v is not None))
    log("done")
    return JobOutcome(job.id, job.label, str(folder), "done", mean, train_seconds, None)


def _share_threads(run: OfficialRun) -> None:
    """Give the official processes this job's share of the cores (``--jobs N`` splits them between
    workers, as for native jobs, through torch's thread count in the worker) unless the user fixed
    ``OMP_NUM_THREADS``: torch and OpenMP kernels read it at start. Without torch loaded
    (an inline run) the processes take every core."""
    import os
    import sys

    # imported by the pool's workers only: an official job itself needs no torch
    torch = sys.modules.get("torch")
    if torch is not None and "OMP_NUM_THREADS" not in os.environ:
        run.env.setdefault("OMP_NUM_THREADS", str(torch.get_num_threads()))


def _failed(
    job: Job,
    folder: Path,
    log: JobLog,
    error: OfficialRunError,
    run: OfficialRun | None,
    started: str,
) -> JobOutcome:
    """Record a failed official job: error.txt ends with the one-line summary `olatbench status`
    shows. The outcome always carries the official command's summary; a disk that refuses the
    records (full, read-only) is said after it, as `olatbench.bench.execute` does for native jobs
    (the job then stays unrecorded and the next run retries)."""
    message = str(error)
    summary, _, details = message.partition("\n")
    outcome = JobOutcome(job.id, job.label, str(folder), "failed", error=summary)
    try:
        write_text(folder / ERROR_FILE, (details + "\n" if details else "") + summary + "\n")
        log(f"FAILED: {summary}")
        results = base_results(job, "failed", started)
        results["error"] = {"type": type(error).__name__, "message": message}
        settings = CodeSettings.from_json(job.official or {"method": job.method})
        results.update(_provenance(job, run, settings))
        write_results(folder / RESULTS_FILE, results)
    except OSError as unrecorded:
        outcome.error = f"{summary} (not recorded in the folder: {unrecorded})"
        outcome.recorded = False
    return outcome


def _provenance(job: Job, run: OfficialRun | None, settings: CodeSettings) -> dict[str, Any]:
    """``method_kind`` and the ``official`` block of results.json."""
    from olatbench.methods.official.cpu_standins import standins_for
    from olatbench.methods.registry import get_spec

    try:
        pin = get_spec(job.method).source
    except KeyError:  # a spec registered in another process only
        pin = None
    commit, dirty = checkout_commit(settings.checkout) if settings.checkout else (None, None)
    return {
        "method_kind": "official",
        "official": {
            "repository": pin.repository if pin else None,
            "pinned_commit": pin.commit if pin else None,
            "status": pin.status if pin else None,
            "commit": commit,
            "local_changes": dirty,
            "matches_pin": None if commit is None or pin is None else commit == pin.commit,
            "settings": settings.to_json(),
            "device": settings.device,
            "standins": list(standins_for(job.method)) if settings.device == "cpu" else [],
            "commands": [record.to_json() for record in run.commands] if run else [],
        },
    }


def _score(
    job: Job, frames: list[Frame], renders: dict[str, Path], encoded_as: str, folder: Path
) -> dict[str, Any]:
    """Score each render against its frame under the job's protocol (in ``job.colourspace``) and
    copy it to ``renders/<split>/<frame id>.png``; returns ``{"mean", "per_image"}``."""
    from olatbench.metrics.protocols import get_protocol

    protocol = get_protocol(job.protocol)
    per_image = {}
    for frame in frames:
        background = colour.convert_colourspace(
            np.asarray(frame.background, np.float32), frame.colourspace, job.colourspace
        )
        pred = np.clip(
            read_prediction(renders[frame.frame_id], job.colourspace, background, encoded_as),
            0.0,
            1.0,
        )
        gt, mask = ground_truth(job, protocol, frame)
        if pred.shape != gt.shape:
            raise OfficialRunError(
                f"{frame.frame_id}: the official render {renders[frame.frame_id]} is "
                f"{pred.shape[1]}×{pred.shape[0]}, the ground truth {gt.shape[1]}×{gt.shape[0]}"
            )
        per_image[frame.frame_id] = score_image(protocol, pred, gt, mask, str(job.device))
        save_render(folder, job.test_split, frame, pred, job.colourspace)
    return {"mean": mean_scores(protocol, per_image), "per_image": per_image}
