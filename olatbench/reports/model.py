"""A format-neutral table: what every layout builds and every writer (LaTeX, Markdown, CSV, HTML)
prints.

A `Table` has a header (rows of spanning column titles above the leaf columns), one or more
`Block`s (the paper's metric blocks, e.g. "PSNR ↑"), each holding `Row`s of `Cell`s. Ranking
(best / second best) is stored on the cells by `olatbench.reports.ranking.rank_table`, so
every writer colours the same cells.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

MISSING = "—"


@dataclass
class Cell:
    """One number (or text such as "RTX 4090"); ``value=None`` prints as "—".

    ``std`` prints as "mean ± std"; ``rank`` is 1 (best), 2 (second best) or None; ``marks`` are
    footnote markers (e.g. "a") appended to the printed text; ``decimals`` is the print precision;
    ``signed`` prints a "+" on positive numbers (differences).
    """

    value: float | str | None
    std: float | None = None
    rank: int | None = None
    marks: tuple[str, ...] = ()
    decimals: int = 4
    std_decimals: int | None = None
    signed: bool = False

    @property
    def number(self) -> float | None:
        """The value as a float, or None when missing, text or NaN."""
        if (
            isinstance(self.value, (int, float))
            and not isinstance(self.value, bool)
            and math.isfinite(self.value)
        ):
            return float(self.value)
        return None

    def text(self) -> str:
        """Plain text: "30.0854", "25.91 ± 1.88", "RTX 4090" or "—" (without footnote marks)."""
        if self.value is None or (isinstance(self.value, float) and not math.isfinite(self.value)):
            return MISSING
        if isinstance(self.value, str):
            return self.value
        body = f"{self.value:{'+' if self.signed else ''}.{self.decimals}f}"
        if self.std is not None and math.isfinite(self.std):
            body += (
                " ± "
                f"{self.std:.{self.decimals if self.std_decimals is None else self.std_decimals}f}"
            )
        return body


@dataclass
class Row:
    """A table row: ``labels`` fill the label columns (e.g. ("Ours",) or ("A: Diff", "Train")).

    Rows with the same non-None ``rank_set`` in a block are ranked against each other, column by
    column; rows with ``rank_set=None`` (published or Δ rows) are never ranked.
    """

    labels: tuple[str, ...]
    cells: list[Cell]
    rank_set: str | None = "all"


@dataclass
class Block:
    """A block of rows under an optional spanning title (e.g. "PSNR ↑").

    ``directions[j]`` is "max" or "min" (which way is better) for column j, or None (not ranked).
    ``rule_before`` lists row indices that start a new group (a horizontal rule is drawn above
    them).
    """

    title: str | None
    rows: list[Row]
    directions: list[str | None]
    rule_before: tuple[int, ...] = ()


@dataclass
class Table:
    """A whole table: caption, protocol line, header rows, blocks and footnotes.

    ``header`` rows are lists of (title, span) whose spans add up to ``len(columns)``; the last
    header row names the leaf columns. ``label_names`` name the label columns (e.g. ("Method",)).
    ``column_rules`` lists leaf-column indices after which a vertical rule is drawn (LaTeX);
    ``rules`` is how its horizontal rules are typeset (LaTeX): "hline" (most of the paper's tables)
    or "booktabs".
    """

    name: str
    caption: str
    protocol: str
    label_names: tuple[str, ...]
    header: list[list[tuple[str, int]]]
    columns: list[str]
    blocks: list[Block]
    footnotes: list[str] = field(default_factory=list)
    column_rules: tuple[int, ...] = ()
    corner: tuple[str, str] = ("Method", "Dataset")
    rules: str = "hline"

    def __post_init__(self) -> None:
        for level, header_row in enumerate(self.header):
            span = sum(width for _, width in header_row)
            if span != len(self.columns):
                raise ValueError(
                    f"table {self.name}: header row {level} spans {span} columns, "
                    f"expected {len(self.columns)}"
                )
        for block in self.blocks:
            if len(block.directions) != len(self.columns):
                raise ValueError(
                    f"table {self.name}: block {block.title!r} has {len(block.directions)} "
                    f"directions for {len(self.columns)} columns"
                )
            for row in block.rows:
                if len(row.cells) != len(self.columns) or len(row.labels) != len(self.label_names):
                    raise ValueError(
                        f"table {self.name}: row {row.labels} does not match the columns"
                    )

    def cell(self, block_title: str | None, labels: tuple[str, ...], column: str) -> Cell:
        """The cell of a row (by labels) and leaf column (by name) in the block with this title."""
        index = self.columns.index(column)
        for block in self.blocks:
            if block.title == block_title:
                for row in block.rows:
                    if row.labels == labels:
                        return row.cells[index]
        raise KeyError(f"table {self.name}: no row {labels} in block {block_title!r}")
