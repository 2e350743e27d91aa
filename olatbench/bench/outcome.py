"""What every job writes about itself, in-process (`olatbench.bench.execute`) or official code
(`olatbench.bench.official`): the outcome reported to the executor, the log, the ``results.json``
skeleton, the ground truth a render is scored against, the per-image scores and the saved renders
with their hashes.

One home for both runners, so an official run and a native run of one scene are scored and recorded
alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.bench.jobs import Job, hash_json
from olatbench.bench.provenance import hardware_identity, library_versions, peak_rss_mb, utc_now
from olatbench.bench.results import SCHEMA_VERSION
from olatbench.datasets import colour
from olatbench.datasets.formats._common import safe_file_stem
from olatbench.datasets.images import write_image
from olatbench.datasets.records import Frame
from olatbench.datasets.synth.mini import data_matches_reference
from olatbench.metrics.evaluate import sha256_file

LOG_FILE = "log.txt"


@dataclass
class JobOutcome:
    """What an executor reports back for one job (picklable)."""

    job_id: str
    label: str
    folder: str
    status: str  # "done" | "failed" | "skipped"
    test_metrics: dict[str, Any] = field(default_factory=dict)
    train_seconds: float | None = None
    render_fps: float | None = None
    error: str | None = None
    # a failure written to the folder (error.txt); False when the disk refused it
    recorded: bool = True


class JobLog:
    """Timestamped human-readable lines appended to the job's ``log.txt``."""

    def __init__(self, folder: Path) -> None:
        self.path = folder / LOG_FILE

    def __call__(self, message: str) -> None:
        stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S")
        with open(self.path, "a", encoding="utf-8") as handle:
            handle.write(f"{stamp} {message}\n")


def finite(value: Any) -> Any:
    """``value``, or None for a non-finite float (JSON has no NaN)."""
    return None if isinstance(value, float) and not math.isfinite(value) else value


def ground_truth(job: Job, protocol: Any, frame: Frame) -> tuple[np.ndarray, np.ndarray | None]:
    """The image a render of ``frame`` is scored against, in ``job.colourspace``: (rgb (H, W, 3),
    mask (H, W) or None). A protocol that names an official ground truth gets it at native
    resolution; otherwise (or when the job resizes) the frame composited on its official background,
    with its alpha as mask for masked protocols."""
    resolution = tuple(job.resolution) if job.resolution else None
    if protocol.ground_truth == "official" and resolution is None:
        return protocol.load_ground_truth(frame, job.scene_format)
    loaded = frame.load(colourspace=job.colourspace, background="official", resolution=resolution)
    return loaded.rgb, (loaded.alpha if protocol.masked else None)


def score_image(
    protocol: Any, pred: np.ndarray, gt: np.ndarray, mask: np.ndarray | None, device: str
) -> dict[str, Any]:
    """One render's scores under ``protocol`` (both images clipped to [0, 1]), non-finite values as
    None."""
    scores = protocol.evaluate(np.clip(pred, 0.0, 1.0), np.clip(gt, 0.0, 1.0), mask, device=device)
    return {key: finite(value) for key, value in scores.items()}


def mean_scores(protocol: Any, per_image: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The protocol's mean over the per-image scores, non-finite values as None."""
    return {key: finite(value) for key, value in protocol.mean(list(per_image.values())).items()}


def render_file(split: str, frame: Frame) -> Path:
    """Where a job keeps its render of ``frame``: ``renders/<split>/<frame id>.png``, relative to
    the job folder."""
    return Path("renders") / split / f"{safe_file_stem(frame.frame_id)}.png"


def save_render(folder: Path, split: str, frame: Frame, pred: np.ndarray, colourspace: str) -> None:
    """Save a render (values in ``colourspace``) as the job's 8-bit sRGB PNG of ``frame``."""
    write_image(
        folder / render_file(split, frame), colour.convert_colourspace(pred, colourspace, "srgb")
    )


def scored_files(frames: list[Frame], folder: Path, split: str) -> dict[str, dict[str, Any]]:
    """sha256 of each frame's saved render (path relative to the job folder) and of its ground-truth
    file."""
    files = {}
    for frame in frames:
        render = render_file(split, frame)
        truth = frame.image_path
        files[frame.frame_id] = {
            "render": render.as_posix(),
            "render_sha256": sha256_file(folder / render),
            "ground_truth": None if truth is None else str(Path(truth).resolve()),
            "ground_truth_sha256": None if truth is None else sha256_file(truth),
        }
    return files


def base_results(job: Job, status: str, started: str) -> dict[str, Any]:
    """The ``results.json`` skeleton of a job (metrics, timing and hashes filled in by the
    runner)."""
    return {
        "schema_version": SCHEMA_VERSION,
        "kind": "run",
        "status": status,
        "job": {
            "id": job.id,
            "method": job.method,
            "variant": job.variant,
            "suite": job.suite,
            "scene": job.scene,
            "seed": job.seed,
            "config": job.config,
            "resolution": list(job.resolution) if job.resolution else None,
        },
        "protocol": {"id": job.protocol, "version": job.protocol_version},
        "metrics": {},
        "timing": {
            "started": started,
            "finished": utc_now(),
            "train_seconds": None,
            "render_fps": None,
        },
        "resources": {
            "device": job.device,
            "peak_rss_mb": round(peak_rss_mb(), 1),
            "cuda_peak_mb": None,
        },
        "hardware": hardware_identity(),
        "model": {"iterations": job.iterations, "num_gaussians": None},
        "versions": library_versions(),
        "hashes": {
            "data_manifest": job.data_manifest,
            "config": hash_json(job.config),
            "code": job.code,
            "data_matches_reference": data_matches_reference(job.scene_path)
            if job.suite == "mini"
            else None,
            "checkpoint": None,
        },
        "files": {},
        "source": None,
        "evaluation": {"test_time_refinement": None, "test_pose_fitting": None},
        "error": None,
        # scores under novel illumination (olatbench.bench.novel_lights), when asked
        "novel_lights": None,
    }


def failed_results(job: Job, error: BaseException, started: str) -> dict[str, Any]:
    """``results.json`` of a job that failed with ``error``."""
    results = base_results(job, "failed", started)
    results["error"] = {"type": type(error).__name__, "message": str(error)}
    return results
