"""Markdown reports show names exactly as written (#38 item 13): a scene called
``<script>…</script>`` or ``a|b`` neither injects HTML nor breaks the table. Checked by rendering
with Python-Markdown (independent of our writer)."""

from __future__ import annotations

import re

import markdown

from olatbench.reports.model import Block, Cell, Row, Table
from olatbench.reports.text import to_markdown

NASTY = [
    "<script>alert(1)",  # no "/": columns are "scene/split" paths
    "a|b",
    "*bold* _it_ `code` [link](http://x)",
    "two\nlines & more",
]


def _table() -> Table:
    columns = [f"{name}/Test" for name in NASTY]
    return Table(
        name="tab:<b>x</b>",
        caption="Scenes <img src=x onerror=alert(1)> | all",
        protocol="p|q",
        label_names=("Method",),
        header=[[(c, 1) for c in columns]],
        columns=columns,
        blocks=[
            Block(
                title="PSNR <i>",
                directions=["max"] * len(columns),
                rows=[Row((name,), [Cell(float(i)) for i in range(len(columns))]) for name in NASTY]
                + [Row(("text cell",), [Cell(name) for name in NASTY])],
            )
        ],
        footnotes=["scene <script>alert(2)</script> had | no runs"],
    )


def test_names_with_html_and_pipes_are_shown_as_written():
    html = markdown.markdown(to_markdown(_table()), extensions=["tables"])
    assert not re.search(r"<(script|img|b|i)\b", html), html
    rows = re.findall(r"<tr>(.*?)</tr>", html, flags=re.S)
    cells = [re.findall(r"<t[hd][^>]*>(.*?)</t[hd]>", row, flags=re.S) for row in rows]
    assert all(len(row) == 1 + len(NASTY) for row in cells), cells  # no "|" split a cell
    header = cells[0]
    assert header[1] == "&lt;script&gt;alert(1) Test" and header[2] == "a|b Test"
    assert [row[0] for row in cells[2 : 2 + len(NASTY)]] == [
        "&lt;script&gt;alert(1)",
        "a|b",
        "*bold* _it_ `code` [link](http://x)",
        "two lines &amp; more",
    ]
    assert "scene &lt;script&gt;alert(2)&lt;/script&gt; had | no runs" in html
