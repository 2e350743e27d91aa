"""Print a list of tables in one format: LaTeX, Markdown, CSV or a self-contained HTML page."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from olatbench.reports.html import to_html
from olatbench.reports.latex import PAPER_COLOURS, packages_comment, standalone_document, to_latex
from olatbench.reports.model import Table
from olatbench.reports.text import join_documents, to_csv, to_markdown

FORMATS = ("latex", "markdown", "csv", "html")
SUFFIXES = {".tex": "latex", ".md": "markdown", ".csv": "csv", ".html": "html", ".htm": "html"}


def format_for(path: str | Path | None, explicit: str | None) -> str:
    """The explicit format, else the one the output file's suffix implies, else Markdown."""
    if explicit:
        if explicit not in FORMATS:
            raise ValueError(f"unknown format {explicit!r}; choose one of {', '.join(FORMATS)}")
        return explicit
    if path is not None and Path(path).suffix.lower() in SUFFIXES:
        return SUFFIXES[Path(path).suffix.lower()]
    return "markdown"


def parse_colours(text: str | None) -> tuple[str, ...]:
    """ "1,0.8,0.8;1,0.9,0.8" -> ("1,0.8,0.8", "1,0.9,0.8"), each three numbers in [0, 1]."""
    if not text:
        return PAPER_COLOURS
    colours = tuple(part.strip() for part in text.split(";") if part.strip())
    for colour in colours:
        parts = colour.split(",")
        if len(parts) != 3 or not all(_unit(part) for part in parts):
            raise ValueError(f"colour {colour!r} is not three comma-separated numbers in [0, 1]")
    return colours


def _unit(text: str) -> bool:
    try:
        return 0.0 <= float(text) <= 1.0
    except ValueError:
        return False


def render_tables(
    tables: Sequence[Table],
    fmt: str,
    *,
    standalone: bool = False,
    colours: Sequence[str] = PAPER_COLOURS,
    rules: str | None = None,
    figures: Sequence[tuple[str, bytes, str | None]] = (),
    notes: Sequence[str] = (),
    title: str = "olatbench report",
    fit: bool = False,
) -> str:
    """All tables in one document of format ``fmt`` (figures — title, PNG or MP4 bytes, link to the
    figure's file or None — and notes are used by HTML only). LaTeX: ``standalone`` a document in
    the portable flavour, else the paper's flavour opened by a comment naming its packages; ``fit``
    shrinks tables wider than the line (`olatbench.reports.latex`)."""
    if fmt == "latex":
        body = "\n".join(
            to_latex(table, colours=colours, rules=rules, portable=standalone, fit=fit)
            for table in tables
        )
        return standalone_document(body) if standalone else packages_comment() + body
    if fmt == "markdown":
        return join_documents([to_markdown(table) for table in tables])
    if fmt == "csv":
        return join_documents([to_csv(table) for table in tables])
    if fmt == "html":
        return to_html(tables, figures, title=title, colours=colours, notes=notes)
    raise ValueError(f"unknown format {fmt!r}; choose one of {', '.join(FORMATS)}")
