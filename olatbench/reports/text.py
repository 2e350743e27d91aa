"""Markdown and CSV for a `Table`.

Markdown cannot colour cells: the best cell is **bold** and the second best *italic* (said in a
legend line under each table). CSV is the wide table as printed: one line per row with a
``block`` column (the metric block), the label columns, then one column per leaf column.
"""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Sequence

from olatbench.reports.model import Cell, Table

LEGEND = "Best in **bold**, second best in *italics*."


# what Markdown acts on; "_" only where it can open or close emphasis
# (not inside a word: "diffuse_shadow")
_MARKDOWN_SPECIAL = re.compile(r"([\\`*\[\]|#!~]|(?<![A-Za-z0-9])_|_(?![A-Za-z0-9]))")


def markdown_text(text: str) -> str:
    """Plain text (a scene or method name, a caption) as Markdown that shows exactly that text:
    ``&``, ``<``, ``>`` become entities (no HTML gets through), the characters Markdown acts on are
    backslash-escaped (``|`` no longer ends a table cell; ``_`` inside a word is left alone, as
    Markdown does), and line breaks become spaces (a table row is one line)."""
    text = " ".join(str(text).splitlines())
    text = text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    return _MARKDOWN_SPECIAL.sub(r"\\\1", text)


def _markdown_cell(cell: Cell) -> str:
    text = markdown_text(cell.text()) + "".join(
        f"<sup>{markdown_text(mark)}</sup>" for mark in cell.marks
    )
    if cell.rank == 1:
        return f"**{text}**"
    if cell.rank == 2:
        return f"*{text}*"
    return text


def _header_title(table: Table, index: int) -> str:
    """A leaf column's title in one line: its header path joined ("Cat Train")."""
    return markdown_text(" ".join(table.columns[index].split("/")))


def to_markdown(table: Table) -> str:
    """The table as a GitHub-flavoured Markdown section (caption, protocol, table, legend,
    footnotes)."""
    labels = [markdown_text(name) for name in table.label_names]
    lines = [
        f"**{markdown_text(table.name)}** — {markdown_text(table.caption)}",
        "",
        f"Protocol: {markdown_text(table.protocol)}",
        "",
    ]
    titles = labels + [_header_title(table, i) for i in range(len(table.columns))]
    lines.append("| " + " | ".join(titles) + " |")
    lines.append("|" + "|".join([" --- "] * len(labels) + [" ---: "] * len(table.columns)) + "|")
    empty = [""] * (len(labels) + len(table.columns) - 1)
    for block in table.blocks:
        if block.title is not None:
            lines.append("| " + " | ".join([f"**{markdown_text(block.title)}**", *empty]) + " |")
        for row in block.rows:
            lines.append(
                "| "
                + " | ".join(
                    [markdown_text(label) for label in row.labels]
                    + [_markdown_cell(c) for c in row.cells]
                )
                + " |"
            )
    ranked = any(cell.rank for block in table.blocks for row in block.rows for cell in row.cells)
    lines.append("")
    if ranked:
        lines.append(LEGEND)
    lines += [f"- {markdown_text(note)}" for note in table.footnotes]
    return "\n".join(lines).rstrip() + "\n"


def to_csv(table: Table) -> str:
    """The table as CSV text: ``block``, the label columns, then the leaf columns as printed."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["block", *[name.lower() for name in table.label_names], *table.columns])
    for block in table.blocks:
        for row in block.rows:
            writer.writerow(
                [
                    block.title or "",
                    *row.labels,
                    *[cell.text() + "".join(cell.marks) for cell in row.cells],
                ]
            )
    return buffer.getvalue()


def join_documents(parts: Sequence[str], separator: str = "\n") -> str:
    """Concatenate several tables' text with one blank line between them."""
    return separator.join(part.rstrip("\n") + "\n" for part in parts)
