"""The figures of an HTML report, gathered from the job folders next to each results.json.

Per scene: a comparison grid (ground truth | each method | error maps) for the chosen test frames,
the decomposition into components when the job saved them, the training curves of every job, and the
relighting sweeps ``olatbench render`` wrote to a job's ``videos/`` (H.264 MP4s only: browsers do
not play mp4v). A figure that cannot be made (data moved, renders missing) is skipped with a note
saying why. Jobs are named by their experiment's label
(`olatbench.reports.experiments.experiment_labels`, the rule the tables use); every experiment has
one colour and one short key in all the figures of a report
(`olatbench.reports.figures.method_colours`, `method_keys`), and each figure's caption says what its
panels show (frame, light, metric) and spells out the keys.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd
from matplotlib.figure import Figure

from olatbench.datasets.errors import DatasetError
from olatbench.reports.experiments import experiment_labels
from olatbench.reports.figures import (
    EMBED_DPI,
    ComparisonRow,
    close,
    comparison_figure,
    decomposition_figure,
    encode,
    method_colours,
    method_keys,
    training_curves_figure,
)
from olatbench.reports.jobfolder import JobFolder, JobFolderError, read_png


@dataclass
class ReportFigure:
    """One figure of the report: a matplotlib ``figure`` (drawn once, written in any format) or an
    H.264 MP4 ``video``."""

    title: str
    figure: Figure | None = None
    video: bytes | None = None
    caption: str = ""  # what the panels show, under the title

    def embedded(self) -> bytes:
        """What the HTML page embeds: the video, or the figure as a PNG."""
        return self.video if self.video is not None else encode(self.figure, "png", EMBED_DPI)

    def close(self) -> None:
        if self.figure is not None:
            close(self.figure)


@dataclass
class LabelledJob:
    """A finished job folder and its experiment's label."""

    label: str
    job: JobFolder

    @property
    def title(self) -> str:
        """``ssdgs/mini (iterations=200), Pixiu seed0``: the label, scene and seed."""
        return f"{self.label}, {self.job.job['scene']} seed{self.job.job['seed']}"


def scene_jobs(frame: pd.DataFrame, notes: list[str]) -> dict[tuple[str, str], list[LabelledJob]]:
    """Finished jobs by (suite, scene), the lowest seed of each experiment; unreadable folders go to
    ``notes``."""
    frame = (
        frame.assign(label=experiment_labels(frame)) if not frame.empty else frame.assign(label="")
    )
    done = (
        frame[frame["status"] == "done"].drop_duplicates("path").sort_values("seed", kind="stable")
    )
    done = done.drop_duplicates(["suite", "scene", "label"])
    groups: dict[tuple[str, str], list[LabelledJob]] = {}
    for _, row in done.iterrows():
        try:
            job = JobFolder.open(Path(row["path"]).parent)
        except JobFolderError as error:
            notes.append(
                f"figures of {row['label']}, {row['scene']} seed{row['seed']} skipped ({error})"
            )
            continue
        groups.setdefault((row["suite"], row["scene"]), []).append(LabelledJob(row["label"], job))
    return groups


def _light_text(position) -> str:
    return "(" + ", ".join(f"{float(v):.2f}" for v in position) + ")"


def comparison_for_scene(
    jobs: Sequence[LabelledJob],
    frame_ids: Sequence[str] = (),
    colours: Mapping[str, str] | None = None,
    keys: Mapping[str, str] | None = None,
) -> tuple[Figure, str]:
    """The comparison grid of one scene's jobs on the given (default: first) test frames, and its
    caption (the frame, light and metric of each panel)."""
    reference = jobs[0].job
    scene = reference.load_scene()
    split = reference.job["test_split"]
    frames = scene.split(split)
    chosen = [f for f in frames if f.frame_id in set(frame_ids)] if frame_ids else frames[:1]
    if not chosen:
        raise JobFolderError(
            f"none of the frames {', '.join(frame_ids)} is in the {split} split of {scene.name}"
        )
    keys = dict(keys) if keys is not None else method_keys(job.label for job in jobs)
    rows = []
    for frame in chosen:
        ground_truth = frame.load(
            colourspace="srgb", background="official", resolution=reference.resolution
        ).rgb
        predictions = [
            (job.label, read_png(job.job.render_path(split, frame.frame_id))) for job in jobs
        ]
        rows.append(ComparisonRow(frame.frame_id, ground_truth, predictions))
    lit = "; ".join(
        f"rows {2 * n - 1}–{2 * n}: {split} frame {frame.frame_id}, lit by a point light at "
        f"{_light_text(frame.light.position)}"
        for n, frame in enumerate(chosen, 1)
    )
    caption = (
        f"{lit} (world units). Top row of each frame: the ground truth (GT, sRGB) and each "
        "experiment's render (its lowest finished seed), titled with its key and its PSNR in dB "
        "against the ground truth; bottom row: each experiment's per-pixel error |render − GT| "
        "(mean absolute error over RGB in sRGB, colour scale 0–0.2). The legend under the grid "
        "spells out the keys."
    )
    return comparison_figure(rows, colours=colours, keys=keys), caption


def decomposition_for_job(job: LabelledJob, frame_id: str | None = None) -> Figure | None:
    """The saved components and final render of one test frame, or None when none were saved."""
    folder = job.job
    split = folder.job["test_split"]
    renders = sorted((folder.folder / "renders" / split).glob("*.png"))
    if not renders:
        return None
    stem = frame_id or renders[0].stem
    components = folder.components(split, stem)
    if not components:
        return None
    images = {name: read_png(path) for name, path in components.items()}
    images["rgb"] = read_png(folder.render_path(split, stem))
    return decomposition_figure(images, title=f"{job.title}, {split} frame {stem}")


def report_figures(
    frame: pd.DataFrame, frame_ids: Sequence[str] = ()
) -> tuple[list[ReportFigure], list[str]]:
    """(figures, notes on skipped figures) for every scene of the collected runs."""
    figures: list[ReportFigure] = []
    notes: list[str] = []
    groups = scene_jobs(frame, notes)
    labels = [job.label for jobs in groups.values() for job in jobs]
    colours, keys = method_colours(labels), method_keys(labels)
    for (suite, scene), jobs in groups.items():
        try:
            grid, caption = comparison_for_scene(jobs, frame_ids, colours, keys)
            figures.append(
                ReportFigure(
                    f"{suite}/{scene}: ground truth, renders and error maps", grid, caption=caption
                )
            )
        except (JobFolderError, DatasetError, ValueError) as error:
            notes.append(f"{suite}/{scene}: comparison grid skipped ({error})")
        for job in jobs:
            try:
                picture = decomposition_for_job(job, frame_ids[0] if frame_ids else None)
            except (JobFolderError, DatasetError) as error:
                notes.append(f"{job.title}: decomposition skipped ({error})")
                continue
            if picture is not None:
                figures.append(ReportFigure(f"{job.title}: decomposition", picture))
        logs = {}
        for job in jobs:
            try:
                logs[job.label] = job.job.train_log()
            except JobFolderError as error:
                notes.append(f"{job.title}: training curve skipped ({error})")
        if logs:
            figures.append(
                ReportFigure(
                    f"{suite}/{scene}: training curves",
                    training_curves_figure(logs, colours=colours, method_key=keys),
                    caption="Training loss and PSNR against step of each experiment's lowest "
                    "finished seed; the legend under the plots spells out the keys.",
                )
            )
        for job in jobs:
            videos, skipped = sweep_videos(job)
            figures += videos
            notes += skipped
    return figures, notes


def sweep_videos(job: LabelledJob) -> tuple[list[ReportFigure], list[str]]:
    """The H.264 sweeps in the job's ``videos/`` folder, and notes on the others
    (mp4v: not playable)."""
    figures, notes = [], []
    for path in sorted((job.job.folder / "videos").glob("*.mp4")):
        data = path.read_bytes()
        # the H.264 sample entry
        if b"avc1" not in data[: 1 << 16] and b"avc1" not in data[-(1 << 16) :]:
            notes.append(
                f"{job.title}: {path.name} is not H.264 (browsers cannot play it); render it again "
                "with 'olatbench[video]' installed"
            )
            continue
        figures.append(ReportFigure(f"{job.title}: {path.stem} sweep", video=data))
    return figures, notes
