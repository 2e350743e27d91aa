"""The novel-illumination table of ``olatbench report``: each method's OLAT test scores beside its
scores under each novel-light condition (results.json's ``novel_lights``, the ``novel:<condition>``
rows of `olatbench.reports.collect`), per scene (mean ± std over seeds) and averaged over the
scenes."""

from __future__ import annotations

from collections.abc import Sequence

import pandas as pd

from olatbench.reports.collect import NOVEL_SPLIT, is_novel_split
from olatbench.reports.layouts import CellLookup, split_rows_layout
from olatbench.reports.model import Table
from olatbench.reports.runs_tables import (
    RunCells,
    expected_scenes,
    seed_text,
    select_runs,
    single_suite,
)

#: The metrics of the table: PSNR (OLAT test and every condition), and over the object without and
#: with the per-channel scale (conditions only).
METRICS = ("psnr", "psnr_object", "psnr_si")


def split_novel(frame: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(the rows of the OLAT splits and job facts, the novel-light rows) of a `collect` frame."""
    novel = frame["split"].map(is_novel_split)
    return frame[~novel], frame[novel]


def novel_lights_table(
    frame: pd.DataFrame,
    *,
    suite: str | None = None,
    methods: Sequence[str] | None = None,
    seeds: str = "mean",
    test_split: str = "test",
) -> Table | None:
    """(method, split) rows, scenes and their average as columns, a PSNR and a scale-invariant PSNR
    block: the OLAT ``test_split`` then each condition and their mean. None when no selected job has
    novel-light scores."""
    selected = select_runs(frame, suite, methods)
    suite = suite or single_suite(selected)
    olat, novel = split_novel(selected)
    if novel.empty:
        return None
    jobs = set(novel["job_id"])
    run_cells = RunCells(
        pd.concat([olat[olat["job_id"].isin(jobs) & (olat["split"] == test_split)], novel]), seeds
    )
    scenes, scene_note = expected_scenes(suite, list(run_cells.frame["scene"]))
    conditions = [split for split in dict.fromkeys(novel["split"]) if split != NOVEL_SPLIT]
    splits = [test_split, *conditions, NOVEL_SPLIT]
    cells = {}
    for row in run_cells.rows:
        for split in splits:
            for metric in METRICS:
                # the OLAT protocol has no scale-invariant PSNR
                if split == test_split and metric != "psnr":
                    continue
                for scene in scenes:
                    cells[(row, scene, split, metric)] = run_cells.cell(
                        row, scene, split, metric, with_std=True
                    )
                cells[(row, "Average", split, metric)] = run_cells.average(
                    row, scenes, split, metric
                )
    protocols = ", ".join(sorted(set(run_cells.frame["protocol"])))
    table = split_rows_layout(
        CellLookup(cells),
        run_cells.rows,
        [*scenes, "Average"],
        splits,
        METRICS,
        name=f"tab:{suite}-novel-lights",
        caption=f"Under novel illumination on the {suite} suite: the OLAT test split, then each "
        "condition (the test cameras under the scene's novel-light ground truth) and their mean; "
        "per scene mean ± std over seeds, Average the mean over scenes.",
        protocol=(
            f"{protocols} (OLAT test, novel lights); suite {suite}; "
            f"{seed_text(run_cells, seeds, True)}"
        ),
        rank_sets={row: "all" for row in run_cells.rows},
    )
    table.footnotes += ([scene_note] if scene_note else []) + run_cells.notes.lines()
    return table
