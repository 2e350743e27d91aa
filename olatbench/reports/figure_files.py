"""The figures of an HTML report as the page embeds them, and (``olatbench report --figures
png|svg|pdf``) as files in ``<page name>_figures/`` beside the page, for a paper:
``01-<title>.pdf``, ``02-…`` in page order."""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

from olatbench.atomic import write_bytes
from olatbench.reports.figures import FILE_DPI, encode
from olatbench.reports.gallery import ReportFigure


def figure_folder(page: str | Path) -> Path:
    """``report_figures/`` beside ``report.html``."""
    page = Path(page)
    return page.with_name(f"{page.stem}_figures")


def file_name(index: int, title: str, suffix: str) -> str:
    """``03-nrhints-pixiu-training-curves.pdf``: the position on the page and the title as a
    file-name slug."""
    slug = re.sub(r"[^a-z0-9]+", "-", title.lower()).strip("-")[:80] or "figure"
    return f"{index:02d}-{slug}.{suffix}"


def page_figures(
    figures: Sequence[ReportFigure], page: str | Path | None, fmt: str
) -> list[tuple[str, bytes, str | None]]:
    """(title and caption, embedded bytes, link) of each figure for
    `olatbench.reports.html.to_html`, closing each figure. With a ``page`` path, the drawn figures
    (not the videos) are also written as ``fmt`` files into `figure_folder` (atomically) and linked
    by their path relative to the page."""
    embedded = []
    folder = figure_folder(page) if page is not None else None
    try:
        for index, figure in enumerate(figures, 1):
            link = None
            if folder is not None and figure.figure is not None:
                name = file_name(index, figure.title, fmt)
                write_bytes(folder / name, encode(figure.figure, fmt, FILE_DPI))
                link = f"{folder.name}/{name}"
            text = f"{figure.title}. {figure.caption}" if figure.caption else figure.title
            embedded.append((text, figure.embedded(), link))
    finally:
        for figure in figures:
            figure.close()
    return embedded
