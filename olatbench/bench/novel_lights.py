"""Score a trained job under novel illumination (issue #57): every test camera rendered under every
condition of the scene's novel-light ground truth (`olatbench.datasets.novel_lights`) by the
`olatbench.bench.relight.Relighter`, scored with the `NOVEL_LIGHTS_PROTOCOL` protocol, into
results.json's ``novel_lights`` block (`olatbench.bench.results`).

Both images are scored in the job's colour space (the one its OLAT test split is scored in): the
render is the relighter's linear image (the sum over the condition's lights, the background counted
once) encoded to it; the ground truth (linear RGB, straight alpha) is composited on the scene's
official background in linear light, as the relighter composites, and encoded alike. The ground
truth's alpha is the object mask of ``psnr_si``.

`score_novel_lights` runs after a job's OLAT evaluation (``run --evaluate novel-lights``: the method
in memory) and `add_novel_lights` on a finished job from its final checkpoint (the runner does it
for finished jobs of a plan asked ``--evaluate novel-lights`` whose results.json has no such block:
no retraining). Renders go to ``renders/novel_lights/<condition>/<frame_id>.png`` (8-bit sRGB).
Memory: one relit image (two running buffers) at a time.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.bench.jobs import Job
from olatbench.bench.outcome import finite, mean_scores, score_image
from olatbench.bench.relight import Relighter, shown
from olatbench.bench.results import read_results, write_results
from olatbench.bench.store import RESULTS_FILE
from olatbench.bench.views import view_camera
from olatbench.datasets import colour, load_scene
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.formats._common import safe_file_stem
from olatbench.datasets.images import read_image, resize_image, write_image
from olatbench.datasets.lighting import EnvironmentMap, Lighting
from olatbench.datasets.novel_lights import condition_names, load_condition
from olatbench.datasets.records import Frame
from olatbench.metrics.protocols import Protocol, get_protocol
from olatbench.progress import progress_bar

NOVEL_LIGHTS_PROTOCOL = "olatbench-v1-novel-lights"
RENDERS = Path("renders") / "novel_lights"
#: What ``run --evaluate`` accepts.
EVALUATIONS = ("novel-lights",)


class NovelLightsError(ValueError):
    """A job that cannot be scored under novel illumination; the message names the file and why."""


@dataclass(frozen=True)
class NovelLightsOptions:
    """``samples``: the environment maps' sample count (None: each lighting file's own; area lights
    always keep the ground truth's points); ``views``: score the first ``views`` test frames of each
    condition (None: all)."""

    samples: int | None = None
    views: int | None = None

    def to_json(self) -> dict[str, int | None]:
        return dataclasses.asdict(self)


def with_map_samples(lighting: Lighting, samples: int | None) -> Lighting:
    """``lighting`` with every environment map drawn in ``samples`` directions (unchanged for None).
    Area lights keep their own count: the ground truth is rendered under exactly the points their
    count gives."""
    if samples is None:
        return lighting
    sources = tuple(
        dataclasses.replace(source, samples=samples)
        if isinstance(source, EnvironmentMap)
        else source
        for source in lighting.sources
    )
    return dataclasses.replace(lighting, sources=sources)


def ground_truth_image(
    path: Path, frame: Frame, colourspace: colour.ColourSpace, resolution: tuple[int, int] | None
) -> tuple[np.ndarray, np.ndarray]:
    """A condition's ground truth of ``frame`` as it is scored: (rgb (H, W, 3) in ``colourspace``,
    composited on the frame's official background in linear light; alpha (H, W)), resized to
    ``resolution`` (width, height) when given; a `DatasetError` naming the file when it is no linear
    RGBA image of the camera's size."""
    pixels = read_image(path)
    if pixels.ndim != 3 or pixels.shape[2] != 4:
        raise DatasetError(
            f"expected linear RGB and alpha (4 channels), found shape {pixels.shape}", path=path
        )
    if pixels.shape[:2] != (frame.camera.height, frame.camera.width):
        raise DatasetError(
            f"image is {pixels.shape[1]}×{pixels.shape[0]} but the test camera of frame "
            f"{frame.frame_id} is {frame.camera.width}×{frame.camera.height}",
            path=path,
        )
    if not np.all(np.isfinite(pixels)):
        raise DatasetError("image holds NaN or Inf pixels", path=path)
    alpha = np.clip(pixels[..., 3], 0.0, 1.0)
    background = colour.convert_colourspace(
        np.asarray(frame.background, np.float32).reshape(3), frame.colourspace, "linear"
    )
    rgb = colour.composite(np.clip(pixels[..., :3], 0.0, None), alpha, background, "straight")
    if resolution is not None and tuple(resolution) != (frame.camera.width, frame.camera.height):
        resized = resize_image(np.concatenate([rgb, alpha[..., None]], axis=2), *resolution)
        rgb, alpha = resized[..., :3], np.clip(resized[..., 3], 0.0, 1.0)
    return colour.convert_colourspace(rgb, "linear", colourspace), alpha


def score_novel_lights(
    relighter: Relighter,
    job: Job,
    folder: str | Path,
    options: NovelLightsOptions | None = None,
    *,
    truth: str | Path | None = None,
    progress: bool = False,
    position: int = 1,
) -> dict[str, Any]:
    """The ``novel_lights`` block of results.json (`olatbench.bench.results.NovelLights`) of
    ``relighter``'s method, trained by ``job``: every condition of the novel-light ground truth of
    ``truth`` (a folder holding ``novel_lights/``; default the job's scene folder), its renders
    written below ``folder``."""
    options = options or NovelLightsOptions()
    scoring = get_protocol(NOVEL_LIGHTS_PROTOCOL)
    truth = Path(truth if truth is not None else job.scene_path)
    frames = {
        frame.frame_id: frame
        for frame in load_scene(job.scene_path, format=job.scene_format).split(job.test_split)
    }
    conditions = [load_condition(truth, name) for name in condition_names(truth)]
    if not conditions:
        raise NovelLightsError(
            f"{truth / 'novel_lights'}: holds no condition (<condition>/lighting.json)"
        )
    for condition in conditions:
        unknown = sorted(set(condition.frames) - set(frames))
        if unknown:
            raise NovelLightsError(
                f"{condition.frames[unknown[0]]}: frame {unknown[0]!r} is not a frame of the "
                f"scene's '{job.test_split}' split ({job.scene_path})"
            )
    chosen = {
        condition.name: [fid for fid in frames if fid in condition.frames][: options.views]
        for condition in conditions
    }
    clock = time.perf_counter()
    blocks = {}
    bar = progress_bar(
        total=sum(map(len, chosen.values())),
        desc=f"{job.label}: novel lights",
        position=position,
        leave=False,
        disable=not progress,
        unit="img",
    )
    try:
        for condition in conditions:
            lights = with_map_samples(condition.lighting, options.samples).sample(
                relighter.reference.up
            )
            per_image = {}
            for frame_id in chosen[condition.name]:
                frame = frames[frame_id]
                linear = relighter.linear(view_camera(frame, job), lights)
                pred = colour.convert_colourspace(linear, "linear", job.colourspace)
                gt, alpha = ground_truth_image(
                    condition.frames[frame_id],
                    frame,
                    job.colourspace,
                    tuple(job.resolution) if job.resolution else None,
                )
                per_image[frame_id] = score_image(scoring, pred, gt, alpha, str(job.device))
                write_image(
                    Path(folder) / RENDERS / condition.name / f"{safe_file_stem(frame_id)}.png",
                    shown(linear),
                )
                bar.update(1)
            blocks[condition.name] = {
                "mean": mean_scores(scoring, per_image),
                "per_image": per_image,
                "lights": len(lights),
            }
    finally:
        bar.close()
    return {
        "protocol": {"id": scoring.id, "version": scoring.version},
        "split": job.test_split,
        "options": options.to_json(),
        "conditions": blocks,
        "mean": conditions_mean(scoring, blocks),
        "seconds": round(time.perf_counter() - clock, 3),
    }


def conditions_mean(
    protocol: Protocol, blocks: Mapping[str, Mapping[str, Any]]
) -> dict[str, float | None]:
    """Per metric, the mean over conditions of each condition's mean (None when any is None)."""
    out: dict[str, float | None] = {}
    for metric in protocol.metrics:
        values = [block["mean"].get(metric) for block in blocks.values()]
        out[metric] = (
            None
            if not values or any(v is None for v in values)
            else finite(math.fsum(values) / len(values))
        )
    return out


def has_novel_lights(results: Mapping[str, Any], options: NovelLightsOptions | None = None) -> bool:
    """Whether a results dict holds novel-light scores of the current protocol version (and, given
    ``options``, made with them)."""
    block = results.get("novel_lights")
    if not isinstance(block, dict):
        return False
    scoring = get_protocol(NOVEL_LIGHTS_PROTOCOL)
    same = block.get("protocol") == {"id": scoring.id, "version": scoring.version}
    return same and (options is None or block.get("options") == options.to_json())


def add_novel_lights(
    folder: str | Path,
    options: NovelLightsOptions | None = None,
    *,
    device: str = "cpu",
    truth: str | Path | None = None,
    progress: bool = False,
) -> dict[str, Any]:
    """Score a finished job under novel illumination from its final checkpoint (no training) and
    write the block into its results.json (atomically; the rest unchanged); returns the block. A
    `RestoreError` or `RelightError` says why the job cannot be rebuilt or relit."""
    from olatbench.bench.relight import restore_relighter

    folder = Path(folder)
    results = read_results(folder / RESULTS_FILE)
    if results["status"] != "done":
        raise NovelLightsError(
            f"{folder / RESULTS_FILE}: the job did not finish (status {results['status']})"
        )
    relighter, job = restore_relighter(folder, device, progress)
    block = score_novel_lights(relighter, job, folder, options, truth=truth, progress=progress)
    # as it is now: written once, with the block added
    results = read_results(folder / RESULTS_FILE)
    results["novel_lights"] = block
    write_results(folder / RESULTS_FILE, results)
    return block


__all__ = [
    "EVALUATIONS",
    "NOVEL_LIGHTS_PROTOCOL",
    "NovelLightsError",
    "NovelLightsOptions",
    "add_novel_lights",
    "conditions_mean",
    "ground_truth_image",
    "has_novel_lights",
    "score_novel_lights",
    "with_map_samples",
]
