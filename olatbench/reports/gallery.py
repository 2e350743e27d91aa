"""The figures of an HTML report, gathered from the job folders next to each results.json.

Per scene: a comparison grid (ground truth | each method | error maps) for the chosen test frames,
the decomposition into components when the job saved them, the training curves of every job, and the relighting
sweeps ``olatbench render`` wrote to a job's ``videos/`` (H.264 MP4s only: browsers do not play mp4v).
A figure that cannot be made (data moved, renders missing) is skipped with a note saying why. Every method (or
method/variant) has one colour in all the figures of a report (`olatbench.reports.figures.method_colours`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd
from matplotlib.figure import Figure

from olatbench.datasets.errors import DatasetError
from olatbench.reports.figures import (
    EMBED_DPI,
    ComparisonRow,
    close,
    comparison_figure,
    decomposition_figure,
    encode,
    method_colours,
    training_curves_figure,
)
from olatbench.reports.jobfolder import JobFolder, JobFolderError, read_png


@dataclass
class ReportFigure:
    """One figure of the report: a matplotlib ``figure`` (drawn once, written in any format) or an H.264 MP4
    ``video``."""

    title: str
    figure: Figure | None = None
    video: bytes | None = None

    def embedded(self) -> bytes:
        """What the HTML page embeds: the video, or the figure as a PNG."""
        return self.video if self.video is not None else encode(self.figure, "png", EMBED_DPI)

    def close(self) -> None:
        if self.figure is not None:
            close(self.figure)


def _job_label(job: JobFolder) -> str:
    return job.job["method"] if job.job["variant"] in ("default", job.job["suite"]) else \
        f"{job.job['method']}/{job.job['variant']}"


def scene_jobs(frame: pd.DataFrame, notes: list[str]) -> dict[tuple[str, str], list[JobFolder]]:
    """Finished jobs by (suite, scene), the lowest seed of each method/variant; unreadable folders go to ``notes``."""
    done = frame[frame["status"] == "done"].drop_duplicates("path").sort_values("seed", kind="stable")
    done = done.drop_duplicates(["suite", "scene", "method", "variant"])
    groups: dict[tuple[str, str], list[JobFolder]] = {}
    for _, row in done.iterrows():
        try:
            job = JobFolder.open(Path(row["path"]).parent)
        except JobFolderError as error:
            notes.append(f"figures of {row['method']}/{row['variant']}/{row['scene']} skipped ({error})")
            continue
        groups.setdefault((row["suite"], row["scene"]), []).append(job)
    return groups


def comparison_for_scene(jobs: Sequence[JobFolder], frame_ids: Sequence[str] = (),
                         colours: Mapping[str, str] | None = None) -> Figure:
    """The comparison grid of one scene's jobs on the given (default: first) test frames."""
    reference = jobs[0]
    scene = reference.load_scene()
    split = reference.job["test_split"]
    frames = scene.split(split)
    chosen = [f for f in frames if f.frame_id in set(frame_ids)] if frame_ids else frames[:1]
    if not chosen:
        raise JobFolderError(f"none of the frames {', '.join(frame_ids)} is in the {split} split of {scene.name}")
    rows = []
    for frame in chosen:
        ground_truth = frame.load(colourspace="srgb", background="official", resolution=reference.resolution).rgb
        predictions = [(_job_label(job), read_png(job.render_path(split, frame.frame_id))) for job in jobs]
        rows.append(ComparisonRow(frame.frame_id, ground_truth, predictions))
    return comparison_figure(rows, colours=colours)


def decomposition_for_job(job: JobFolder, frame_id: str | None = None) -> Figure | None:
    """The saved components and final render of one test frame, or None when none were saved."""
    split = job.job["test_split"]
    renders = sorted((job.folder / "renders" / split).glob("*.png"))
    if not renders:
        return None
    stem = frame_id or renders[0].stem
    components = job.components(split, stem)
    if not components:
        return None
    images = {name: read_png(path) for name, path in components.items()}
    images["rgb"] = read_png(job.render_path(split, stem))
    return decomposition_figure(images, title=f"{job.label}, frame {stem}")


def report_figures(frame: pd.DataFrame, frame_ids: Sequence[str] = ()) -> tuple[list[ReportFigure], list[str]]:
    """(figures, notes on skipped figures) for every scene of the collected runs."""
    figures: list[ReportFigure] = []
    notes: list[str] = []
    groups = scene_jobs(frame, notes)
    colours = method_colours(_job_label(job) for jobs in groups.values() for job in jobs)
    for (suite, scene), jobs in groups.items():
        try:
            figures.append(ReportFigure(f"{suite}/{scene}: ground truth, renders and error maps",
                                        comparison_for_scene(jobs, frame_ids, colours)))
        except (JobFolderError, DatasetError, ValueError) as error:
            notes.append(f"{suite}/{scene}: comparison grid skipped ({error})")
        for job in jobs:
            try:
                picture = decomposition_for_job(job, frame_ids[0] if frame_ids else None)
            except (JobFolderError, DatasetError) as error:
                notes.append(f"{job.label}: decomposition skipped ({error})")
                continue
            if picture is not None:
                figures.append(ReportFigure(f"{job.label}: decomposition", picture))
        logs = {}
        for job in jobs:
            try:
                logs[_job_label(job)] = job.train_log()
            except JobFolderError as error:
                notes.append(f"{job.label}: training curve skipped ({error})")
        if logs:
            figures.append(ReportFigure(f"{suite}/{scene}: training curves", training_curves_figure(logs,
                                                                                                    colours=colours)))
        for job in jobs:
            videos, skipped = sweep_videos(job)
            figures += videos
            notes += skipped
    return figures, notes


def sweep_videos(job: JobFolder) -> tuple[list[ReportFigure], list[str]]:
    """The H.264 sweeps in the job's ``videos/`` folder, and notes on the others (mp4v: not playable)."""
    figures, notes = [], []
    for path in sorted((job.folder / "videos").glob("*.mp4")):
        data = path.read_bytes()
        if b"avc1" not in data[:1 << 16] and b"avc1" not in data[-(1 << 16):]:  # the H.264 sample entry
            notes.append(f"{job.label}: {path.name} is not H.264 (browsers cannot play it); render it again with "
                         "'olatbench[video]' installed")
            continue
        figures.append(ReportFigure(f"{job.label}: {path.stem} sweep", video=data))
    return figures, notes
