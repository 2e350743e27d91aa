"""Regenerate each of the paper's tables from the published numbers alone.

`paper_table(name)` builds the table in the paper's layout, ranks it with the paper's rules
(`PAPER_RANKING`) and compares the computed best / second-best cells with the paper's own
colouring (``paper_rank`` in the CSV). Where they disagree the numbers win and the table gets a
footnote listing each disagreement.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import pandas as pd

from olatbench.metrics.registry import find_metric, metric_names
from olatbench.reports.layouts import (
    CellLookup,
    metric_columns_layout,
    metric_title,
    overview_layout,
    scenes_layout,
    split_rows_layout,
    split_title,
)
from olatbench.reports.model import Cell, Table
from olatbench.reports.published import PAPER_TABLES, published_table, table_id
from olatbench.reports.ranking import rank_table

SUITE_TITLES = {"nrhints": "NRHints", "gs3": "GS3", "sssgs": "SSS-GS", "all": "Average"}
PROTOCOL = "published numbers: SSD-GS, ICLR 2026 (as printed in the paper)"


@dataclass(frozen=True)
class Ranking:
    """How a paper table colours its cells: ``top`` ranks, columns with at least ``min_values``
    numbers, and, when ``average_only``, only the "Average" columns."""

    top: int = 2
    min_values: int = 2
    average_only: bool = False


# The rules each paper table is typeset with (LaTeX): the appendix ablation tables use booktabs, the
# others \hline.
PAPER_RULES: dict[str, str] = {"ablation-scenes": "booktabs", "shadow-on-sss": "booktabs"}

PAPER_RANKING: dict[str, Ranking] = {
    "real": Ranking(),
    "gs3": Ranking(),
    "sssgs": Ranking(min_values=3),
    "sssgs-overview": Ranking(min_values=3),
    "ablation": Ranking(),
    "ablation-scenes": Ranking(),
    "shadow-on-sss": Ranking(top=1, average_only=True),
    "relighting-baselines": Ranking(top=1),
}

CAPTIONS = {
    "real": "Comparison on the real NRHints scenes (paper Table 1(a)).",
    "gs3": "Comparison on the GS3 synthetic scenes (paper Table 1(b)).",
    "sssgs": (
        "Per-scene comparison on the SSS-GS synthetic scenes, 60K iterations (paper appendix "
        "table)."
    ),
    "sssgs-overview": (
        "Comparison with SSS-GS and KiloOSF on the SSS-GS synthetic scenes (paper Table 1(c))."
    ),
    "ablation": "Ablation study on the real scene Pixiu (paper Table 2).",
    "ablation-scenes": "Ablation study on real and synthetic scenes (paper appendix table).",
    "shadow-on-sss": "Applying the shadow term to the SSS component (paper appendix table).",
    "relighting-baselines": (
        "Expanded relighting baselines TensoIR and R3DG on GS3 (paper appendix table)."
    ),
}


def _cells(rows: pd.DataFrame) -> dict[tuple[str, str, str, str], Cell]:
    cells = {}
    for _, row in rows.iterrows():
        number = row["number"]
        std = None if pd.isna(row["std"]) else float(row["std"])
        if pd.isna(number):
            cell = Cell(str(row["value"]))
        elif std is not None or find_metric(row["metric"]) is None:
            std_decimals = None if std is None else int(row["std_decimals"])
            cell = Cell(
                float(number), std=std, decimals=int(row["decimals"]), std_decimals=std_decimals
            )
        else:
            cell = Cell(float(number), decimals=4)
        cells[(row["method"], row["scene"], row["split"], row["metric"])] = cell
    return cells


def _unique(values: pd.Series) -> list[str]:
    return list(dict.fromkeys(values))


def _average_last(scenes: list[str]) -> list[str]:
    return [s for s in scenes if s != "Average"] + (["Average"] if "Average" in scenes else [])


def _ablation_set(label: str) -> str:
    """Compositions A-F and schedules H-K are ranked separately, as in the paper."""
    return "composition" if label[:1] in "ABCDEF" else "schedule"


def build_paper_table(name: str) -> tuple[Table, pd.DataFrame]:
    """The unranked table for a paper table name, and the published rows it came from."""
    rows = published_table(name)
    lookup = CellLookup(_cells(rows))
    methods = _unique(rows["method"])
    label = table_id(name)
    caption, protocol = CAPTIONS[name], PROTOCOL
    metrics = [m for m in metric_names() if m in set(rows["metric"])]  # the registry's order
    splits = [s for s in ("train", "test") if s in set(rows["split"])]
    if name in ("real", "gs3", "sssgs"):
        scenes = _average_last(_unique(rows["scene"]))
        table = scenes_layout(
            lookup, methods, scenes, splits, metrics, name=label, caption=caption, protocol=protocol
        )
    elif name == "sssgs-overview":
        table = overview_layout(
            lookup, methods, splits, metrics, name=label, caption=caption, protocol=protocol
        )
    elif name == "ablation":
        sets = {method: _ablation_set(method) for method in methods}
        first_schedule = [i for i, m in enumerate(methods) if sets[m] == "schedule"][:1]
        table = metric_columns_layout(
            lookup,
            methods,
            _unique(rows["scene"])[0],
            splits,
            metrics,
            name=label,
            caption=caption,
            protocol=protocol,
            rank_sets=sets,
            rule_before=first_schedule,
        )
    else:
        scene_suite = dict(zip(rows["scene"], rows["suite"], strict=False))
        scenes = _average_last(_unique(rows["scene"]))
        groups = None
        if name != "relighting-baselines":
            groups = [
                (SUITE_TITLES[suite], sum(scene_suite[s] == suite for s in scenes))
                for suite in _unique(pd.Series([scene_suite[s] for s in scenes]))
            ]
        if name == "ablation-scenes":
            sets = {method: _ablation_set(method) for method in methods}
            rule_rows = [m for m in methods if sets[m] == "schedule"][:1]
        else:
            sets, rule_rows = {method: "all" for method in methods}, []
        table = split_rows_layout(
            lookup,
            methods,
            scenes,
            splits,
            metrics,
            name=label,
            caption=caption,
            protocol=protocol,
            rank_sets=sets,
            scene_groups=groups,
            rule_before_rows=rule_rows,
        )
    return table, rows


def rank_disagreements(table: Table, rows: pd.DataFrame) -> list[str]:
    """Cells whose computed rank differs from the paper's colouring, as readable sentences."""
    paper = {
        (r["method"], r["scene"], r["split"], r["metric"]): (
            None if pd.isna(r["paper_rank"]) else int(r["paper_rank"])
        )
        for _, r in rows.iterrows()
    }
    computed = _computed_ranks(table, rows)
    words = {1: "best", 2: "second best", None: "uncoloured"}
    paper_words = {1: "colours it best", 2: "colours it second best", None: "leaves it uncoloured"}
    notes = []
    for key, paper_rank in paper.items():
        ours = computed.get(key)
        if key in computed and ours != paper_rank:
            method, scene, split, metric = key
            notes.append(
                f"{method}, {scene} {split_title(split)} {metric.upper()}: the paper "
                f"{paper_words[paper_rank]}, its numbers make it {words[ours]}"
            )
    return notes


def _computed_ranks(
    table: Table, rows: pd.DataFrame
) -> dict[tuple[str, str, str, str], int | None]:
    """Map each published key to the rank its cell received (matching cells by identity of
    position)."""
    ranks = {}
    for _, r in rows.iterrows():
        key = (r["method"], r["scene"], r["split"], r["metric"])
        cell = _find(table, *key)
        if cell is not None:
            ranks[key] = cell.rank
    return ranks


def _find(table: Table, method: str, scene: str, split: str, metric: str) -> Cell | None:
    title = metric_title(metric)
    candidates = []
    if table.label_names == ("Method", "Split"):
        candidates.append((title, (method, split_title(split)), scene))
    else:
        candidates += [
            (title, (method,), f"{scene}/{split_title(split)}"),
            (None, (method,), f"{split_title(split)} Set/{title}"),
            (None, (method,), f"{split_title(split)} (Average)/{title}"),
        ]
    for block_title, labels, column in candidates:
        if column in table.columns:
            try:
                return table.cell(block_title, labels, column)
            except KeyError:
                continue
    return None


def paper_table(name: str) -> Table:
    """One of the paper's tables (`PAPER_TABLES` names), ranked, with footnotes on colouring
    disagreements."""
    if name not in PAPER_TABLES:
        raise KeyError(f"unknown paper table {name!r}; choose one of {', '.join(PAPER_TABLES)}")
    table, rows = build_paper_table(name)
    table.rules = PAPER_RULES.get(name, "hline")
    ranking = PAPER_RANKING[name]
    columns = (lambda column: column.startswith("Average")) if ranking.average_only else None
    rank_table(table, top=ranking.top, min_values=ranking.min_values, columns=columns)
    if _has_missing(table):
        table.footnotes.append("— : not reported in the paper.")
    for note in rank_disagreements(table, rows):
        table.footnotes.append(f"Colouring follows the numbers; {note}.")
    return table


def _has_missing(table: Table) -> bool:
    return any(
        cell.value is None or (isinstance(cell.value, float) and math.isnan(cell.value))
        for block in table.blocks
        for row in block.rows
        for cell in row.cells
    )
