"""The paper's table layouts, filled from a mapping (row, scene, split, metric) -> `Cell`.

Both the paper's own numbers (`olatbench.reports.paper`) and a user's runs
(`olatbench.reports.runs_tables`) go through these builders, so both print identically.

* `scenes_layout`: methods as rows, scenes × {Train, Test} as columns, one block per metric
  (Table 1).
* `overview_layout`: per-split averages of each metric, then FPS, training time and device
  (Table 1(c)).
* `metric_columns_layout`: rows as given, {Train, Test} × metrics as columns for one scene
  (Table 2).
* `split_rows_layout`: (row, split) as rows, scenes (grouped by dataset) + Average as columns, one
  block per metric (the appendix ablation, shadow-on-SSS and relighting-baseline tables).
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from olatbench.metrics.registry import find_metric
from olatbench.reports.model import Block, Cell, Row, Table

CellKey = tuple[str, str, str, str]  # (row, scene, split, metric)

#: Ranked columns that are no image metric (the metrics' directions come from
#: `olatbench.metrics.registry`).
COLUMN_DIRECTIONS = {"fps": "max"}
SPLIT_TITLES = {"train": "Train", "test": "Test", "val": "Val", "novel": "Novel lights (mean)"}


@dataclass
class CellLookup:
    """Cells by (row, scene, split, metric); a missing key yields ``missing(key)``
    (default: a bare "—")."""

    cells: Mapping[CellKey, Cell]
    missing: Callable[[CellKey], Cell] | None = None

    def __call__(self, row: str, scene: str, split: str, metric: str) -> Cell:
        key = (row, scene, split, metric)
        if key in self.cells:
            return copy.copy(self.cells[key])
        return self.missing(key) if self.missing is not None else Cell(None)


def metric_title(metric: str) -> str:
    """A metric's column heading with its direction's arrow (``PSNR ↑``, from the metric registry);
    other columns as named."""
    registered = find_metric(metric)
    return registered.heading if registered is not None else metric


def split_title(split: str) -> str:
    """``Test``, ``Train``, ...; a novel-light condition's split (``novel:<condition>``) as
    ``under <condition>``."""
    if split.startswith("novel:"):
        return f"under {split.partition(':')[2]}"
    return SPLIT_TITLES.get(split, split.capitalize())


def _direction(metric: str) -> str | None:
    registered = find_metric(metric)
    return registered.direction if registered is not None else COLUMN_DIRECTIONS.get(metric)


def scenes_layout(
    lookup: CellLookup,
    rows: Sequence[str],
    scenes: Sequence[str],
    splits: Sequence[str],
    metrics: Sequence[str],
    *,
    name: str,
    caption: str,
    protocol: str,
    rank_sets: Mapping[str, str | None] | None = None,
    scene_titles: Mapping[str, str] | None = None,
) -> Table:
    """Methods × (scene, split) with one block per metric, as in the paper's Table 1."""
    titles = scene_titles or {}
    columns = [
        f"{titles.get(scene, scene)}/{split_title(split)}" for scene in scenes for split in splits
    ]
    header = [
        [(titles.get(scene, scene), len(splits)) for scene in scenes],
        [(split_title(split), 1) for _ in scenes for split in splits],
    ]
    blocks = []
    for metric in metrics:
        block_rows = [
            Row(
                (row,),
                [lookup(row, scene, split, metric) for scene in scenes for split in splits],
                rank_set=(rank_sets or {}).get(row, "all"),
            )
            for row in rows
        ]
        blocks.append(Block(metric_title(metric), block_rows, [_direction(metric)] * len(columns)))
    rules = tuple(len(splits) * (i + 1) - 1 for i in range(len(scenes) - 1))
    return Table(name, caption, protocol, ("Method",), header, columns, blocks, column_rules=rules)


def overview_layout(
    lookup: CellLookup,
    rows: Sequence[str],
    splits: Sequence[str],
    metrics: Sequence[str],
    *,
    name: str,
    caption: str,
    protocol: str,
    scene: str = "Average",
    extras: Sequence[tuple[str, str, str]] = (
        ("fps", "FPS", "test"),
        ("train_time", "Train T.", "-"),
        ("gpu", "GPU", "-"),
    ),
    rank_sets: Mapping[str, str | None] | None = None,
) -> Table:
    """Per-split averages (mean ± std over scenes) of each metric, then FPS, training time and
    device.

    ``extras`` are (metric, column title, split) of the "Other Metrics" columns.
    """
    columns, directions = [], []
    for split in splits:
        for metric in metrics:
            columns.append(f"{split_title(split)} (Average)/{metric_title(metric)}")
            directions.append(_direction(metric))
    columns += [title for _, title, _ in extras]
    directions += [None] * len(extras)
    top = [(f"{split_title(split)} (Average)", len(metrics)) for split in splits] + [
        ("Other Metrics", len(extras))
    ]
    leaf = [(metric_title(metric), 1) for _ in splits for metric in metrics] + [
        (t, 1) for _, t, _ in extras
    ]
    header = [top, leaf]
    block_rows = []
    for row in rows:
        cells = [lookup(row, scene, split, metric) for split in splits for metric in metrics]
        cells += [lookup(row, scene, split, metric) for metric, _, split in extras]
        block_rows.append(Row((row,), cells, rank_set=(rank_sets or {}).get(row, "all")))
    rules = tuple(len(metrics) * (i + 1) - 1 for i in range(len(splits)))
    return Table(
        name,
        caption,
        protocol,
        ("Method",),
        header,
        columns,
        [Block(None, block_rows, directions)],
        column_rules=rules,
    )


def metric_columns_layout(
    lookup: CellLookup,
    rows: Sequence[str],
    scene: str,
    splits: Sequence[str],
    metrics: Sequence[str],
    *,
    name: str,
    caption: str,
    protocol: str,
    rank_sets: Mapping[str, str | None],
    rule_before: Sequence[int] = (),
) -> Table:
    """Rows × ({Train, Test} × metrics) for one scene: the paper's Table 2 (ablations on Pixiu)."""
    columns = [
        f"{split_title(split)} Set/{metric_title(metric)}" for split in splits for metric in metrics
    ]
    header = [
        [(f"{split_title(split)} Set", len(metrics)) for split in splits],
        [(metric_title(metric), 1) for _ in splits for metric in metrics],
    ]
    directions = [_direction(metric) for _ in splits for metric in metrics]
    block_rows = [
        Row(
            (row,),
            [lookup(row, scene, split, metric) for split in splits for metric in metrics],
            rank_set=rank_sets.get(row, "all"),
        )
        for row in rows
    ]
    rules = tuple(len(metrics) * (i + 1) - 1 for i in range(len(splits) - 1))
    return Table(
        name,
        caption,
        protocol,
        ("Method",),
        header,
        columns,
        [Block(None, block_rows, directions, tuple(rule_before))],
        column_rules=rules,
    )


def split_rows_layout(
    lookup: CellLookup,
    rows: Sequence[str],
    scenes: Sequence[str],
    splits: Sequence[str],
    metrics: Sequence[str],
    *,
    name: str,
    caption: str,
    protocol: str,
    rank_sets: Mapping[str, str | None],
    scene_groups: Sequence[tuple[str, int]] | None = None,
    rule_before_rows: Sequence[str] = (),
) -> Table:
    """(row, split) × scenes with one block per metric: the paper's appendix tables.

    ``scene_groups`` adds a top header row of (dataset title, number of scenes) spans.
    ``rank_sets[row]`` names the set a row is ranked in; each split is ranked separately.
    """
    columns = list(scenes)
    header = [[(scene, 1) for scene in scenes]]
    if scene_groups:
        header.insert(0, list(scene_groups))
    rules = []
    if scene_groups:
        position = 0
        for _, span in scene_groups[:-1]:
            position += span
            rules.append(position - 1)
    blocks = []
    for metric in metrics:
        block_rows, starts = [], []
        for row in rows:
            if row in rule_before_rows:
                starts.append(len(block_rows))
            rank_set = rank_sets.get(row, "all")
            for split in splits:
                block_rows.append(
                    Row(
                        (row, split_title(split)),
                        [lookup(row, scene, split, metric) for scene in scenes],
                        rank_set=None if rank_set is None else f"{rank_set}/{split}",
                    )
                )
        blocks.append(
            Block(
                metric_title(metric), block_rows, [_direction(metric)] * len(columns), tuple(starts)
            )
        )
    return Table(
        name,
        caption,
        protocol,
        ("Method", "Split"),
        header,
        columns,
        blocks,
        column_rules=tuple(rules),
    )
