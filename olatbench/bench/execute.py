"""Run one job: load the views, train (resuming from the last checkpoint), evaluate, write results.

The order inside the job folder makes every state recoverable: ``job.json`` and ``config.json``
first, checkpoints during training (the last one at the final step), renders and ``results.json``
after evaluation, ``DONE`` last. A job killed at any point resumes from its newest checkpoint with
the RNG states restored, so it reaches the result of an uninterrupted run.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import time
import traceback
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch

from olatbench.atomic import write_json, write_text
from olatbench.bench.checkpoints import (
    CheckpointUnreadable,
    list_checkpoints,
    load_checkpoint,
    prune_checkpoints,
    restore_rng_states,
    rng_states,
    save_checkpoint,
    seed_everything,
)
from olatbench.bench.health import RunHealth, background_psnr, record_warnings
from olatbench.bench.init_points import load_init_points
from olatbench.bench.jobs import Job
from olatbench.bench.outcome import (
    JobLog,
    JobOutcome,
    base_results,
    failed_results,
    finite,
    ground_truth,
    mean_scores,
    save_render,
    score_image,
    scored_files,
)
from olatbench.bench.plan import load_method_class
from olatbench.bench.provenance import utc_now
from olatbench.bench.results import read_results, write_results
from olatbench.bench.reuse import adopt_finished_model, find_reusable
from olatbench.bench.store import (
    DONE_FILE,
    ERROR_FILE,
    JOB_FILE,
    RESULTS_FILE,
    TRAIN_LOG_FILE,
    job_lock,
    job_state,
    set_aside_damaged,
)
from olatbench.bench.views import VIEWS_FILE, load_views, view_camera
from olatbench.datasets import colour, load_scene
from olatbench.datasets.formats._common import safe_file_stem
from olatbench.datasets.images import write_image
from olatbench.datasets.records import Camera, Frame, LoadedImage, PointLight, Scene
from olatbench.gaussians.host_sync import allowed_host_sync
from olatbench.methods.backends import format_backends
from olatbench.methods.base import Method, Views
from olatbench.methods.evaluation_protocol import EvaluationProtocol, evaluation_protocol
from olatbench.metrics.evaluate import sha256_file
from olatbench.metrics.protocols import Protocol, get_protocol
from olatbench.progress import progress_bar, progress_write

WARMUP_RENDERS = 1


def run_job(job: Job, progress: bool = True, position: int = 1) -> JobOutcome:
    """Run ``job`` to completion; a failure is recorded in the folder and returned, never raised.

    ``KeyboardInterrupt`` is not a failure: the job stays partial and resumes on the next run. A job
    whose folder is locked by another process (running elsewhere) is returned as ``skipped``. The
    folder's state is read again once the lock is held, since another process may have finished the
    job after this one planned it: a finished job is returned as ``done`` with its recorded metrics
    and nothing in its folder changes (``--force`` clears folders before the run, not here), and a
    folder that now holds another job is left alone and the job fails. A damaged job (a finished job
    whose results.json or job.json was damaged) has those files set aside as ``<name>.damaged``
    first, said in log.txt and on stderr, and is rerun. A folder that cannot be written
    (read-only, full disk) fails the job, not the plan: the failure is recorded in the folder where
    the disk still allows it, and always in the outcome.
    """
    folder = Path(job.folder)
    try:
        with job_lock(folder) as acquired:
            if not acquired:
                return JobOutcome(
                    job.id, job.label, str(folder), "skipped", error="running in another process"
                )
            # under the lock: "done" and "stale" are final (running: this one)
            state = job_state(folder, job.id)
            if state.state == "done":
                return _finished_outcome(job, folder)
            if state.state == "stale":
                return JobOutcome(
                    job.id,
                    job.label,
                    str(folder),
                    "failed",
                    recorded=False,
                    error=f"{folder} {state.message} (written after this run planned it); rerun "
                    "with --force to replace it, or choose another --output",
                )
            _keep_damaged(job, folder)
            return _run_locked(job, folder, progress, position)
    except OSError as error:  # the folder or its lock file cannot be made: nothing was written
        return JobOutcome(
            job.id,
            job.label,
            str(folder),
            "failed",
            recorded=False,
            error=f"cannot write the job folder {folder}: {error.strerror or error}",
        )


def _keep_damaged(job: Job, folder: Path) -> None:
    """Set a damaged job's files aside (`set_aside_damaged`) and say so, with what was wrong, in
    log.txt and on stderr: the rerun then repairs the job without overwriting what a user edited."""
    for path, problem in set_aside_damaged(folder, job.id):
        line = f"{job.label}: {problem}; kept as {path}; re-evaluating the job"
        JobLog(folder)(line)
        progress_write(line)


def _finished_outcome(job: Job, folder: Path) -> JobOutcome:
    """The outcome of a job found finished (by `job_state`): its metrics and timings as its
    results.json records."""
    results = read_results(folder / RESULTS_FILE)
    timing = results.get("timing") or {}
    test = results["metrics"].get(job.test_split, {}).get("mean", {})
    return JobOutcome(
        job.id,
        job.label,
        str(folder),
        "done",
        test,
        timing.get("train_seconds"),
        timing.get("render_fps"),
    )


def _run_locked(job: Job, folder: Path, progress: bool, position: int) -> JobOutcome:
    log = JobLog(folder)
    started = utc_now()
    try:
        # the authors' code in its own process (olatbench.bench.official)
        if job.official is not None:
            from olatbench.bench.official import run_official_job

            return run_official_job(job, folder, log, started)
        return _run(job, folder, log, progress, position, started)
    except Exception as error:
        return _record_failure(job, folder, log, error, started)
    finally:
        # a folder that cannot be written holds no views file either
        with contextlib.suppress(OSError):
            (folder / VIEWS_FILE).unlink(missing_ok=True)


def _record_failure(
    job: Job, folder: Path, log: JobLog, error: Exception, started: str
) -> JobOutcome:
    """Write error.txt, the log line and a failed results.json, as far as the disk allows; the
    outcome says what could not be written (the job then stays partial or pending, and the next run
    retries it)."""
    outcome = JobOutcome(
        job.id, job.label, str(folder), "failed", error=f"{type(error).__name__}: {error}"
    )
    try:
        write_text(folder / ERROR_FILE, traceback.format_exc())
        log(f"FAILED: {type(error).__name__}: {error}")
        write_results(folder / RESULTS_FILE, failed_results(job, error, started))
    except OSError as unrecorded:
        outcome.error += f" (not recorded in the folder: {unrecorded})"
        outcome.recorded = False
    return outcome


def _run(
    job: Job, folder: Path, log: JobLog, progress: bool, position: int, started: str
) -> JobOutcome:
    for stale in (ERROR_FILE, RESULTS_FILE, DONE_FILE):
        (folder / stale).unlink(missing_ok=True)
    write_json(folder / JOB_FILE, job.to_json())
    write_json(folder / "config.json", job.config)
    log(
        f"job {job.id}: {job.method} on {job.suite}/{job.label}, {job.iterations} iterations, "
        f"device {job.device}"
    )

    if torch.device(job.device).type == "cuda":
        torch.cuda.reset_peak_memory_stats(job.device)
    method, protocol, train_views, scene = prepare_method(job, log, progress, position)
    reused = _adopt_reusable_model(job, folder, log)
    train_seconds = _train(method, train_views, job, folder, log, progress, position)

    metrics: dict[str, Any] = {}
    files: dict[str, dict[str, Any]] = {}
    render_fps, refinement = None, None
    for split, frames in (
        (job.train_split, scene.split(job.train_split)),
        (job.test_split, scene.split(job.test_split)),
    ):
        # a float16 stack is for training, not for scoring
        exact = train_views.images.dtype == np.float32
        gt_images = train_views.images if split == job.train_split and exact else None
        metrics[split], fps, refined = evaluate_split(
            method, frames, job, folder, split, gt_images, progress, position, protocol=protocol
        )
        files[split] = scored_files(frames, folder, split)
        if split == job.test_split:
            render_fps, refinement = fps, refined
        log(
            f"{split}: "
            + ", ".join(f"{k} {v:.4f}" for k, v in metrics[split]["mean"].items() if v is not None)
        )

    novel = _novel_lights(method, train_views, job, folder, log, progress, position)
    results = _done_results(job, started, metrics, train_seconds, render_fps, method)
    if novel is not None:
        results["novel_lights"] = novel
    results["model"]["reused_from"] = reused
    results["files"] = files
    checkpoints = list_checkpoints(folder)
    results["hashes"]["checkpoint"] = sha256_file(checkpoints[-1][1]) if checkpoints else None
    results["evaluation"]["test_time_refinement"] = refinement
    if protocol.fitting is not None:
        results["evaluation"]["test_pose_fitting"] = {
            "mode": protocol.fitting,
            "split": job.test_split,
            "frames": protocol.fitted_views() or {},
        }
    write_results(folder / RESULTS_FILE, results)
    prune_checkpoints(folder, keep=1)
    write_text(folder / DONE_FILE, job.id + "\n")
    log("done")
    return JobOutcome(
        job.id,
        job.label,
        str(folder),
        "done",
        metrics[job.test_split]["mean"],
        train_seconds,
        render_fps,
    )


def _novel_lights(
    method: Method,
    train_views: Views,
    job: Job,
    folder: Path,
    log: JobLog,
    progress: bool,
    position: int,
) -> dict[str, Any] | None:
    """When the job asks (``job.novel_lights``), the ``novel_lights`` block of its results: the
    trained method, as it is in memory, scored under the scene's novel-light ground truth
    (`olatbench.bench.novel_lights`)."""
    if job.novel_lights is None:
        return None
    from olatbench.bench.novel_lights import NovelLightsOptions, score_novel_lights
    from olatbench.bench.relight import Relighter

    block = score_novel_lights(
        Relighter.for_views(method, train_views),
        job,
        folder,
        NovelLightsOptions(**job.novel_lights),
        progress=progress,
        position=position,
    )
    log(
        "novel lights: "
        + ", ".join(
            f"{name} {scores['mean']['psnr']:.2f} dB"
            for name, scores in block["conditions"].items()
            if scores["mean"].get("psnr") is not None
        )
    )
    return block


def prepare_method(
    job: Job,
    log: Callable[[str], None] = lambda line: None,
    progress: bool = False,
    position: int = 1,
) -> tuple[Method, EvaluationProtocol, Views, Scene]:
    """Seed every RNG with ``job.seed``, read the scene, load its training views
    (with the job's initial points), build the method from ``job.config`` and its evaluation
    protocol, attaching the test views when the protocol fits their poses while the method trains:
    everything a job does before ``method.setup``, in the runner's order. So ``method.setup(views,
    job.device, job.seed)`` followed by ``train_step(0)``, ``train_step(1)``, ... reproduces the
    job's training bit for bit (``benchmarks/numerics_trace.py`` relies on it). ``log`` receives the
    job log's lines."""
    seed_everything(job.seed)
    scene = load_scene(job.scene_path, format=job.scene_format)
    clock = time.perf_counter()
    train_views = load_views(scene.split(job.train_split), job, progress, position)
    log(f"loaded {len(train_views)} training views in {time.perf_counter() - clock:.1f} s")
    if job.init_points:
        train_views = dataclasses.replace(
            train_views, points=load_init_points(job.init_points, job.init_points_digest)
        )
        log(f"starting from the {len(train_views.points)} points of {job.init_points}")
    method_class = load_method_class(job)
    method = method_class(method_class.resolve_config(None, **job.config))
    protocol = evaluation_protocol(method)
    # the protocol fits the test views' poses/lights while the method trains
    if protocol.fitting is not None:
        test_views = load_views(
            scene.split(job.test_split), job, progress, position, frame=train_views.frame
        )
        protocol.attach_test_views(test_views)
        log(f"loaded {len(test_views)} test views for test_pose_fitting={protocol.fitting}")
    return method, protocol, train_views, scene


def _adopt_reusable_model(job: Job, folder: Path, log: JobLog) -> dict[str, str] | None:
    """Start from a finished sibling job's model when it is the same experiment
    (`olatbench.bench.reuse`); returns ``{"job_id", "folder"}`` of the source
    (folder relative to the job's), or None."""
    if not job.reuse or list_checkpoints(folder):
        return None
    found = find_reusable(job)
    if found is None:
        return None
    source, source_id = found
    adopt_finished_model(job, source, source_id)
    relative = os.path.relpath(source, folder)
    log(
        f"same experiment as job {source_id} ({relative}: equal config, data, code and seed): its "
        "trained model is evaluated here instead of training again (--no-reuse trains anyway)"
    )
    return {"job_id": source_id, "folder": Path(relative).as_posix()}


def _train(
    method: Method, views: Views, job: Job, folder: Path, log: JobLog, progress: bool, position: int
) -> float:
    """Set the method up, resume from the newest checkpoint, train to the end; returns train
    seconds.

    Train seconds: ``setup`` plus the optimisation steps (checkpoint writes excluded), accumulated
    over resumed sessions.
    """
    before_setup = rng_states()

    def set_up() -> None:  # from the same RNG states each time: a redone set-up is the first one
        restore_rng_states(before_setup)
        method.setup(views, job.device, job.seed)

    clock = time.perf_counter()
    set_up()
    setup_seconds = time.perf_counter() - clock
    log(
        f"device {job.device}; backends: "
        f"{format_backends(method.backends()) or 'not reported by the method'}"
    )
    floor = background_psnr(views.images, views.background) if views.images is not None else None
    health = RunHealth(method.num_gaussians, floor, job.iterations)
    start, train_seconds = 0, setup_seconds
    payload = _resume(method, folder, job, log, set_up)
    if payload is not None:
        start, train_seconds = payload["step"], payload["train_seconds"]
    iterations = job.iterations
    train_log = _TrainLog(folder / TRAIN_LOG_FILE, start)
    every = job.checkpoint_every or max(1, iterations // 10)
    log_every = max(1, iterations // 2000)
    last_save = time.monotonic()
    bar = progress_bar(
        total=iterations,
        initial=start,
        desc=job.label,
        position=position,
        leave=False,
        disable=not progress,
        dynamic_ncols=True,
        mininterval=0.5,
    )
    try:
        postfix_time = 0.0
        for step in range(start, iterations):
            clock = time.perf_counter()
            result = method.train_step(step)
            done = step + 1
            # read from the device only at the logging interval (timed: it waits for the device)
            scalars = None
            if done % log_every == 0 or done == iterations:
                scalars = read_scalars(result)
            train_seconds += time.perf_counter() - clock
            bar.update(1)
            if scalars is not None:
                health.observe(done, scalars)
                train_log.write({"step": done, "seconds": round(train_seconds, 4), **scalars})
                if time.monotonic() - postfix_time > 0.5:
                    bar.set_postfix(
                        {k: f"{scalars[k]:.4g}" for k in ("loss", "psnr") if k in scalars},
                        refresh=False,
                    )
                    postfix_time = time.monotonic()
            due = done % every == 0 or time.monotonic() - last_save > 60 * job.checkpoint_minutes
            if due or done == iterations:
                scalars = scalars or read_scalars(result)
                train_log.flush()
                save_checkpoint(
                    folder, done, method.state_dict(), job.id, train_seconds, job.keep_checkpoints
                )
                last_save = time.monotonic()
                log(
                    f"checkpoint at step {done}: "
                    + ", ".join(f"{k} {v:.5g}" for k, v in scalars.items())
                )
                for warning in record_warnings(folder, health.check()):
                    log(f"WARNING: {warning}")
                    progress_write(f"WARNING {job.label}: {warning}")
    finally:
        bar.close()
        train_log.close()
    # learning-free: its one state (built by setup) is what restore loads
    if iterations == 0 and payload is None:
        save_checkpoint(folder, 0, method.state_dict(), job.id, train_seconds, job.keep_checkpoints)
        log("learning-free method (0 iterations): no training steps; state saved at step 0")
    elif start >= iterations:
        log("training already complete; evaluating")
    return train_seconds


def read_scalars(result: Mapping[str, Any]) -> dict[str, float]:
    """A training step's scalars as floats: numbers, 0-d tensors or lazy scalars
    (`Method.train_step`), read only at the logging interval and at checkpoints, the one host sync a
    GPU step leaves to the runner (allowance "logging" of `olatbench.gaussians.host_sync`)."""
    with allowed_host_sync("logging"):
        return {key: float(value) for key, value in result.items()}


def _resume(
    method: Method, folder: Path, job: Job, log: JobLog, set_up: Callable[[], None]
) -> dict[str, Any] | None:
    """Load the newest checkpoint of the folder that loads into ``method`` and restore its RNG
    states; returns its payload (None: start from step 0).

    A checkpoint that does not load, whatever the reason — torch cannot read it (cut short by a
    crash, a full disk, a damaged file, not a zip, an object ``weights_only`` refuses), it is not a
    checkpoint of this format or of this job, or the method refuses its state (another config,
    another method) — is renamed to ``<name>.unreadable`` (kept, no longer listed or pruned) and the
    next older one is tried; each such step is said, with the file and the reason, in log.txt and on
    stderr. After the method refused a state (which may have changed part of it), it is set up again
    (``set_up``, from the RNG states of the first set-up) before the next one is tried or training
    starts.
    """
    for _, path in reversed(list_checkpoints(folder)):
        try:
            payload = load_checkpoint(path, job.id)
        except CheckpointUnreadable as error:
            _set_aside(path, str(error), job, log)
            continue
        try:
            method.load_state_dict(payload["method"])
            restore_rng_states(payload["rng"])
        # the method's own check (e.g. another model's tensors): any reason sets it aside
        except Exception as error:
            reason = str(error).strip().splitlines()[0] if str(error).strip() else "no message"
            _set_aside(
                path,
                f"{path}: does not load into {job.method} ({type(error).__name__}: {reason})",
                job,
                log,
            )
            set_up()
            continue
        log(f"resumed from {path.name} (step {payload['step']} of {job.iterations})")
        return payload
    return None


def _set_aside(path: Path, reason: str, job: Job, log: JobLog) -> None:
    """Rename a checkpoint that does not load to ``<name>.unreadable`` and say so in log.txt and on
    stderr."""
    aside = path.with_name(path.name + ".unreadable")
    os.replace(path, aside)
    message = f"{job.label}: {reason}; kept as {aside.name}, trying the next older checkpoint"
    log(message)
    progress_write(message)


class _TrainLog:
    """``train_log.jsonl``: one JSON object per logged step; on resume, lines past the checkpoint
    go."""

    def __init__(self, path: Path, start: int) -> None:
        kept = []
        if path.is_file():
            for line in path.read_text(encoding="utf-8").splitlines():
                try:
                    entry = json.loads(line)
                except json.JSONDecodeError:
                    continue  # a line cut short by a kill
                if isinstance(entry, dict) and entry.get("step", math.inf) <= start:
                    kept.append(line)
        write_text(path, "".join(line + "\n" for line in kept))
        self.handle = open(path, "a", encoding="utf-8")  # noqa: SIM115 - closed by close()

    def write(self, entry: dict[str, Any]) -> None:
        self.handle.write(json.dumps({k: finite(v) for k, v in entry.items()}) + "\n")

    def flush(self) -> None:
        self.handle.flush()

    def close(self) -> None:
        self.handle.close()


def _to_numpy(image: torch.Tensor) -> np.ndarray:
    return image.detach().to(torch.float32).cpu().numpy()


def evaluate_split(
    method: Method,
    frames: list[Frame],
    job: Job,
    folder: Path,
    split: str,
    gt_images: np.ndarray | None,
    progress: bool,
    position: int,
    *,
    protocol: EvaluationProtocol,
) -> tuple[dict[str, Any], float | None, dict[str, Any] | None]:
    """Render every frame of a split, save ``renders/<split>/<frame_id>.png`` (8-bit sRGB) and score
    it.

    Scores are computed in the suite's evaluation space (``job.colourspace``: sRGB for PNG data,
    gamma 2.2 for GS³ EXRs, as the official scripts display them), against the ground truth
    `_ground_truth` picks. Returns the metrics block ``{"mean": ..., "per_image": {frame_id:
    ...}}``, the render FPS (renders only, after `WARMUP_RENDERS` warm-up renders; CUDA
    synchronised) and, when the evaluation protocol refines test views (``protocol.refines``, test
    split only), ``{"split", "seconds", "frames": {frame_id: summary}}``: each view's pose/light is
    then fitted to its image (training space) before the render that is scored.
    """
    scoring = get_protocol(job.protocol)
    refinement = _Refinement(split) if split == job.test_split and protocol.refines else None
    render_seconds, per_image = 0.0, {}
    with torch.no_grad():
        _warm_up(method, frames, job)
        for index, frame in enumerate(
            progress_bar(
                frames,
                desc=f"{job.label}: {split}",
                position=position,
                leave=False,
                disable=not progress,
            )
        ):
            camera, light, loaded = view_camera(frame, job), frame.light, None
            if refinement is not None:
                camera, light, loaded = refinement.refine(protocol, frame, camera, light, job)
            output, seconds = _timed_render(method, camera, light, job.device)
            render_seconds += seconds
            pred = np.clip(_to_numpy(output["rgb"]), 0.0, 1.0)
            gt, mask = _ground_truth(job, scoring, frame, index, gt_images, loaded)
            per_image[frame.frame_id] = score_image(scoring, pred, gt, mask, str(job.device))
            _save_outputs(folder, split, frame, pred, output, job)
    fps = len(frames) / render_seconds if render_seconds > 0 else None
    return (
        {"mean": mean_scores(scoring, per_image), "per_image": per_image},
        fps,
        refinement.record() if refinement is not None else None,
    )


def _warm_up(method: Method, frames: list[Frame], job: Job) -> None:
    """Render the first `WARMUP_RENDERS` frames untimed (kernel compilation, caches, allocator)."""
    for frame in frames[:WARMUP_RENDERS]:
        method.render(view_camera(frame, job), frame.light)


def _timed_render(
    method: Method, camera: Camera, light: PointLight, device: str
) -> tuple[dict[str, torch.Tensor], float]:
    """The method's render of one view and its wall-clock seconds (CUDA synchronised before and
    after)."""
    cuda = torch.device(device).type == "cuda"
    if cuda:
        torch.cuda.synchronize(device)
    clock = time.perf_counter()
    output = method.render(camera, light)
    if cuda:
        torch.cuda.synchronize(device)
    return output, time.perf_counter() - clock


class _Refinement:
    """Test-time refinement of one split's views by the evaluation protocol: each view's image is
    loaded (training space, official background), the protocol fits the view to it, and the
    summaries and seconds are kept."""

    def __init__(self, split: str) -> None:
        self.split, self.seconds, self.frames = split, 0.0, {}

    def refine(
        self,
        protocol: EvaluationProtocol,
        frame: Frame,
        camera: Camera,
        light: PointLight,
        job: Job,
    ) -> tuple[Camera, PointLight, LoadedImage]:
        """The camera and light to render ``frame`` with, and the image the protocol was given."""
        clock = time.perf_counter()
        resolution = tuple(job.resolution) if job.resolution else None
        loaded = frame.load(
            colourspace=job.colourspace, background="official", resolution=resolution
        )
        refined = protocol.refine(camera, light, loaded.rgb)
        if refined is not None:
            camera, light = refined.camera, refined.light
            self.frames[frame.frame_id] = {k: finite(float(v)) for k, v in refined.summary.items()}
        self.seconds += time.perf_counter() - clock
        return camera, light, loaded

    def record(self) -> dict[str, Any]:
        """``evaluation.test_time_refinement`` of results.json."""
        return {"split": self.split, "seconds": round(self.seconds, 3), "frames": self.frames}


def _ground_truth(
    job: Job,
    scoring: Protocol,
    frame: Frame,
    index: int,
    gt_images: np.ndarray | None,
    loaded: LoadedImage | None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """The ground truth (H, W, 3) and mask (H, W) or None a render of ``frame`` is scored against.

    Protocols that reproduce an official pipeline score against its ground truth
    (e.g. 8-bit truncated), which exists at the native resolution only
    (`olatbench.bench.outcome.ground_truth`). Otherwise ``gt_images`` (the already loaded training
    views, row ``index``) when the protocol is unmasked, else the image test-time refinement was
    given (``loaded``), else the frame loaded afresh. Masked protocols get the ground truth's alpha
    as mask.
    """
    resolution = tuple(job.resolution) if job.resolution else None
    official_gt = scoring.ground_truth == "official" and resolution is None
    if gt_images is not None and not scoring.masked and not official_gt:
        return gt_images[index], None
    if loaded is not None and not official_gt:  # the image refine was given
        return loaded.rgb, (loaded.alpha if scoring.masked else None)
    return ground_truth(job, scoring, frame)


def _save_outputs(
    folder: Path,
    split: str,
    frame: Frame,
    pred: np.ndarray,
    output: dict[str, torch.Tensor],
    job: Job,
) -> None:
    """Save the scored render and, when the job asks (test split only), the method's components."""
    save_render(folder, split, frame, pred, job.colourspace)
    if job.save_components and split == job.test_split:
        _save_components(
            output, folder / "components" / split, safe_file_stem(frame.frame_id), job.colourspace
        )


def _save_components(
    output: dict[str, torch.Tensor], directory: Path, stem: str, colourspace: str
) -> None:
    """Save each non-``rgb`` component: 3-channel ones encoded like ``rgb`` (sRGB 8-bit), scalar
    maps as is."""
    for name, tensor in output.items():
        if name == "rgb" or not isinstance(tensor, torch.Tensor) or tensor.dim() not in (2, 3):
            continue
        image = _to_numpy(tensor)
        if image.ndim == 3 and image.shape[2] == 3:
            image = colour.convert_colourspace(image, colourspace, "srgb")
        elif image.ndim == 3 and image.shape[2] != 1:
            continue
        write_image(directory / name / f"{stem}.png", np.clip(image, 0.0, 1.0))


def _done_results(
    job: Job,
    started: str,
    metrics: dict[str, Any],
    train_seconds: float,
    render_fps: float | None,
    method: Method,
) -> dict[str, Any]:
    results = base_results(job, "done", started)
    results["metrics"] = metrics
    results["timing"].update(
        train_seconds=round(train_seconds, 3),
        render_fps=round(render_fps, 3) if render_fps else None,
    )
    if torch.device(job.device).type == "cuda":
        results["resources"]["cuda_peak_mb"] = round(
            torch.cuda.max_memory_allocated(job.device) / 2**20, 1
        )
    results["model"]["num_gaussians"] = method.num_gaussians
    results["resources"].update(backend_fields(job, method))
    return results


def backend_fields(job: Job, method: Method) -> dict[str, Any]:
    """``device`` and ``backends`` (stage -> implementation, see `olatbench.methods.backends`) for
    results.json."""
    return {"device": job.device, "backends": method.backends()}
