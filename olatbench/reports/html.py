"""A self-contained HTML report: tables with the paper's cell colours, figures embedded as base64
PNG and relighting sweeps as base64 H.264 MP4 (``<video>``, played by every current browser). A
figure also written as a file (``olatbench report --figures pdf``) links to it from its caption. A
table's LaTeX label (``tab:mini``) is the anchor of its heading, not text on the page."""

from __future__ import annotations

import base64
import html
import struct
from collections.abc import Sequence

from olatbench.reports.latex import PAPER_COLOURS
from olatbench.reports.model import Cell, Table

STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 0.3em 0; font-size: 0.85em; }
th, td { border: 1px solid #bbb; padding: 2px 6px; text-align: center; }
td.label { text-align: left; white-space: nowrap; }
tr.block th { background: #f3f3f3; }
p.note { font-size: 0.8em; color: #555; margin: 0.1em 0; }
figure { margin: 1em 0; } figcaption { font-size: 0.85em; color: #444; }
img { max-width: 100%; }
"""


def _css_colour(rgb: str) -> str:
    red, green, blue = (round(float(part) * 255) for part in rgb.split(","))
    return f"rgb({red},{green},{blue})"


def _cell(cell: Cell, colours: Sequence[str]) -> str:
    text = html.escape(cell.text()) + "".join(f"<sup>{html.escape(m)}</sup>" for m in cell.marks)
    if cell.rank is not None and cell.rank <= len(colours):
        return f'<td style="background:{_css_colour(colours[cell.rank - 1])}">{text}</td>'
    return f"<td>{text}</td>"


def table_html(table: Table, colours: Sequence[str] = PAPER_COLOURS) -> str:
    """One table as an HTML fragment (caption, table, protocol, footnotes)."""
    labels = len(table.label_names)
    width = labels + len(table.columns)
    parts = [f'<h2 id="{html.escape(table.name)}">{html.escape(table.caption)}</h2>', "<table>"]
    for level, header_row in enumerate(table.header):
        corner = (
            ""
            if level
            else (
                f'<th colspan="{labels}" rowspan="{len(table.header)}">'
                f"{html.escape(' / '.join(table.corner))}</th>"
            )
        )
        cells = "".join(
            f'<th colspan="{span}">{html.escape(title)}</th>' for title, span in header_row
        )
        parts.append(f"<tr>{corner}{cells}</tr>")
    for block in table.blocks:
        if block.title is not None:
            parts.append(
                f'<tr class="block"><th colspan="{width}">{html.escape(block.title)}</th></tr>'
            )
        for row in block.rows:
            label_cells = "".join(
                f'<td class="label">{html.escape(label)}</td>' for label in row.labels
            )
            parts.append(f"<tr>{label_cells}{''.join(_cell(c, colours) for c in row.cells)}</tr>")
    parts.append("</table>")
    parts.append(f'<p class="note">Protocol: {html.escape(table.protocol)}</p>')
    parts += [f'<p class="note">{html.escape(note)}</p>' for note in table.footnotes]
    return "\n".join(parts)


def is_mp4(data: bytes) -> bool:
    """Whether ``data`` is an MP4 (ISO base media file: an ``ftyp`` box first)."""
    return data[4:8] == b"ftyp"


def png_css_width(data: bytes) -> int | None:
    """The width in CSS pixels (1/96 inch) at which a PNG shows at the size it was drawn for: its
    pixel width over the resolution of its ``pHYs`` chunk (matplotlib writes the figure's dpi
    there); None without one."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        return None
    width = struct.unpack(">I", data[16:20])[0]
    offset = 8
    while offset + 8 <= len(data):
        length, kind = struct.unpack(">I4s", data[offset : offset + 8])
        if kind == b"pHYs" and length == 9:
            per_unit, _, unit = struct.unpack(">IIB", data[offset + 8 : offset + 17])
            return round(width * 96 / (per_unit * 0.0254)) if unit == 1 and per_unit else None
        if kind == b"IDAT":
            return None
        offset += 12 + length
    return None


def figure_html(title: str, data: bytes, link: str | None = None) -> str:
    """A PNG, or an MP4 as a looping muted ``<video>``, embedded as a base64 data URI with its
    caption; ``link``: a relative path to the figure's file, linked from the caption."""
    encoded = base64.b64encode(data).decode("ascii")
    if is_mp4(data):
        media = (
            '<video controls loop muted playsinline style="max-width:100%" '
            f'title="{html.escape(title)}" src="data:video/mp4;base64,{encoded}"></video>'
        )
    else:
        # a 150-dpi figure at its drawn size, sharp on high-density screens
        width = png_css_width(data)
        sized = f' width="{width}"' if width else ""
        media = f'<img alt="{html.escape(title)}"{sized} src="data:image/png;base64,{encoded}">'
    caption = html.escape(title)
    if link is not None:
        caption += (
            f' (<a href="{html.escape(link)}">{html.escape(link.rsplit(".", 1)[-1].upper())}</a>)'
        )
    return f"<figure>{media}<figcaption>{caption}</figcaption></figure>"


def to_html(
    tables: Sequence[Table],
    figures: Sequence[tuple[str, bytes, str | None]] = (),
    title: str = "olatbench report",
    colours: Sequence[str] = PAPER_COLOURS,
    notes: Sequence[str] = (),
) -> str:
    """A complete page: every table, every figure (title, PNG or MP4 bytes, link to its file or
    None), then notes (e.g. skipped figures); nothing external but the linked figure files."""
    legend = (
        f'<p class="note">Best cells <span style="background:{_css_colour(colours[0])}">like '
        "this</span>"
        + (
            f', second best <span style="background:{_css_colour(colours[1])}">like this</span>'
            if len(colours) > 1
            else ""
        )
        + ".</p>"
    )
    body = [f"<h1>{html.escape(title)}</h1>", legend]
    body += [table_html(table, colours) for table in tables]
    body += [figure_html(name, data, link) for name, data, link in figures]
    body += [f'<p class="note">{html.escape(note)}</p>' for note in notes]
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>{html.escape(title)}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n"
        + "\n".join(body)
        + "\n</body>\n</html>\n"
    )
