"""Markdown and CSV for a `Table`.

Markdown cannot colour cells: the best cell is **bold** and the second best *italic* (said in a
legend line under each table). CSV is the wide table as printed: one line per row with a
``block`` column (the metric block), the label columns, then one column per leaf column.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence

from olatbench.reports.model import Cell, Table

LEGEND = "Best in **bold**, second best in *italics*."


def _markdown_cell(cell: Cell) -> str:
    text = cell.text() + ("".join(f"<sup>{mark}</sup>" for mark in cell.marks))
    if cell.rank == 1:
        return f"**{text}**"
    if cell.rank == 2:
        return f"*{text}*"
    return text


def _header_title(table: Table, index: int) -> str:
    """A leaf column's title in one line: its header path joined ("Cat Train")."""
    return " ".join(table.columns[index].split("/"))


def to_markdown(table: Table) -> str:
    """The table as a GitHub-flavoured Markdown section (caption, protocol, table, legend, footnotes)."""
    labels = list(table.label_names)
    lines = [f"**{table.name}** — {table.caption}", "", f"Protocol: {table.protocol}", ""]
    titles = labels + [_header_title(table, i) for i in range(len(table.columns))]
    lines.append("| " + " | ".join(titles) + " |")
    lines.append("|" + "|".join([" --- "] * len(labels) + [" ---: "] * len(table.columns)) + "|")
    empty = [""] * (len(labels) + len(table.columns) - 1)
    for block in table.blocks:
        if block.title is not None:
            lines.append("| " + " | ".join([f"**{block.title}**", *empty]) + " |")
        for row in block.rows:
            lines.append("| " + " | ".join(list(row.labels) + [_markdown_cell(c) for c in row.cells]) + " |")
    ranked = any(cell.rank for block in table.blocks for row in block.rows for cell in row.cells)
    lines.append("")
    if ranked:
        lines.append(LEGEND)
    lines += [f"- {note}" for note in table.footnotes]
    return "\n".join(lines).rstrip() + "\n"


def to_csv(table: Table) -> str:
    """The table as CSV text: ``block``, the label columns, then the leaf columns as printed."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["block", *[name.lower() for name in table.label_names], *table.columns])
    for block in table.blocks:
        for row in block.rows:
            writer.writerow([block.title or "", *row.labels,
                             *[cell.text() + "".join(cell.marks) for cell in row.cells]])
    return buffer.getvalue()


def join_documents(parts: Sequence[str], separator: str = "\n") -> str:
    """Concatenate several tables' text with one blank line between them."""
    return separator.join(part.rstrip("\n") + "\n" for part in parts)
