"""LaTeX for a `Table` in the paper's style: diagbox corner, multirow/multicolumn headers, metric
blocks, best / second-best cells as ``\\cellcolor[rgb]{1,0.8,0.8}`` / ``{1,0.9,0.8}``.

Strings in the model are plain text; `latex_text` escapes them and turns the few symbols the
tables use (↑ ↓ ± — ≈ < >, "GS3") into LaTeX; the en-dash "–" stays as the paper's source writes it
(``E: Full – S``; pdflatex reads UTF-8).

Two flavours. The paper's (`PAPER_PACKAGES`: a table to paste into a paper whose preamble loads
them; multirow and diagbox are not in a default TeX Live such as Debian's
``texlive-latex-recommended``, so the text opens with a comment naming every package it needs).
``portable=True`` (what ``standalone=True`` uses): the same table without multirow and diagbox (a
group's label in its first row; the corner's two titles in the top and bottom header rows), needing
only `PORTABLE_PACKAGES`, all in ``texlive-latex-recommended``; ``standalone=True`` wraps it in a
document that compiles with pdflatex there. Tables keep their natural width; ``fit=True`` shrinks
one wider than the line to the line's width (never enlarges it).
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from olatbench.reports.model import Cell, Table

PAPER_COLOURS = ("1,0.8,0.8", "1,0.9,0.8")  # best (red), second best (orange), as rgb in [0, 1]
#: ``fit=True``: a table wider than the line is shrunk to it; a narrower one keeps its width
#: (graphicx's \width is the natural width inside \resizebox's arguments).
FIT_WIDTH = r"\ifdim\width>\linewidth\linewidth\else\width\fi"
#: The box a table is set in first, so that its notes can be as wide as it is.
BOX = r"\olatbenchtable"
#: The packages of the portable flavour (and, with geometry, of the standalone document): all in
#: texlive-latex-recommended.
PORTABLE_PACKAGES = ("[table]{xcolor}", "{colortbl}", "{booktabs}", "{graphicx}")
#: The packages of the paper's flavour.
PAPER_PACKAGES = (*PORTABLE_PACKAGES, "{multirow}", "{diagbox}")
#: Where the paper flavour's two extra packages come from (checked: both .sty files are in Debian
#: 12's texlive-latex-extra 2022.20230122-4, neither in texlive-latex-recommended).
EXTRA_PACKAGES_HINT = (
    "multirow and diagbox are not in texlive-latex-recommended: install texlive-latex-extra "
    "(Debian/Ubuntu) or 'tlmgr install multirow diagbox', or use --standalone, which needs neither"
)

_ESCAPES = {
    "\\": r"\textbackslash{}",
    "&": r"\&",
    "%": r"\%",
    "$": r"\$",
    "#": r"\#",
    "_": r"\_",
    "{": r"\{",
    "}": r"\}",
    "^": r"\^{}",
    "~": r"\textasciitilde{}",
    "↑": r"$\uparrow$",
    "↓": r"$\downarrow$",
    "±": r"$\pm$",
    "—": "---",
    "≈": r"$\approx$",
    "<": r"$<$",
    ">": r"$>$",
    "Δ": r"$\Delta$",
    "−": r"$-$",
    "×": r"$\times$",
}


def latex_text(text: str) -> str:
    """Escape plain text for LaTeX; "GS3" becomes "GS$^3$" as in the paper."""
    escaped = "".join(_ESCAPES.get(char, char) for char in text)
    escaped = re.sub(r"\bGS3\b", r"GS$^3$", escaped)
    return escaped.replace("$$", "")


def _cell(cell: Cell, colours: Sequence[str]) -> str:
    text = latex_text(cell.text())
    if cell.std is not None and cell.number is not None:
        text = "$" + cell.text().replace(" ± ", r" \pm ") + "$"
    if cell.marks:
        text += "$^{" + ",".join(cell.marks) + "}$"
    if cell.rank is not None and cell.rank <= len(colours):
        text = rf"\cellcolor[rgb]{{{colours[cell.rank - 1]}}}{text}"
    return text


def _block_title(title: str) -> str:
    name, _, arrow = title.partition(" ")
    return rf"\textbf{{{latex_text(name)}}}" + (f" {latex_text(arrow)}" if arrow else "")


def _column_spec(table: Table) -> str:
    spec = "l" * len(table.label_names) + "|"
    for index in range(len(table.columns)):
        spec += "c" + ("|" if index in table.column_rules else "")
    return spec


def _corners(table: Table, portable: bool) -> list[str]:
    """The corner cell of each header row: the paper's diagbox spanning them all (multirow), or,
    ``portable``, the column titles' name (``Dataset``) in the top row and the row labels'
    (``Method``) in the bottom one."""
    levels = len(table.header)
    rows, columns = (latex_text(title) for title in table.corner)
    if portable:
        corners = (
            [f"{rows} / {columns}"] if levels == 1 else [columns] + [""] * (levels - 2) + [rows]
        )
    else:
        corner = rf"\diagbox{{{rows}}}{{{columns}}}"
        corners = [rf"\multirow{{{levels}}}{{*}}{{{corner}}}" if levels > 1 else corner] + [""] * (
            levels - 1
        )
    labels = len(table.label_names)
    return [
        rf"\multicolumn{{{labels}}}{{c|}}{{{corner}}}" if labels > 1 else corner
        for corner in corners
    ]


def _header_lines(table: Table, rules: dict[str, str], portable: bool = False) -> list[str]:
    levels = len(table.header)
    labels = len(table.label_names)
    corners = _corners(table, portable)
    lines = []
    first_column = labels + 1
    for level, header_row in enumerate(table.header):
        parts = [corners[level]]
        position = 0
        for title, span in header_row:
            position += span
            bar = "|" if position - 1 in table.column_rules else ""
            # single columns take their rule from the column spec; spans need their own
            parts.append(
                rf"\multicolumn{{{span}}}{{c{bar}}}{{{latex_text(title)}}}"
                if span > 1
                else latex_text(title)
            )
        lines.append(" & ".join(parts) + r" \\")
        if level < levels - 1:
            lines.append(rf"\cline{{{first_column}-{labels + len(table.columns)}}}")
    lines.append(rules["mid"])
    return lines


def _body_lines(
    table: Table, colours: Sequence[str], rules: dict[str, str], portable: bool = False
) -> list[str]:
    width = len(table.label_names) + len(table.columns)
    lines = []
    for number, block in enumerate(table.blocks):
        if number > 0:
            lines.append(rules["mid"])
        if block.title is not None:
            lines += [
                rf"\multicolumn{{{width}}}{{c}}{{{_block_title(block.title)}}} \\",
                rules["mid"],
            ]
        previous = None
        for index, row in enumerate(block.rows):
            if index in block.rule_before:
                lines.append(rules["mid"])
            labels = list(row.labels)
            if len(labels) > 1:
                if labels[0] == previous:
                    labels[0] = ""
                else:
                    if previous is not None and index not in block.rule_before:
                        lines.append(rules["mid"])
                    span = sum(
                        1 for later in block.rows[index:] if later.labels[0] == row.labels[0]
                    )
                    labels[0] = (
                        rf"\multirow{{{span}}}{{*}}{{{latex_text(row.labels[0])}}}"
                        if span > 1 and not portable
                        else latex_text(row.labels[0])
                    )
                previous = row.labels[0]
                labels[1:] = [latex_text(label) for label in labels[1:]]
            else:
                labels = [latex_text(label) for label in labels]
            lines.append(" & ".join(labels + [_cell(cell, colours) for cell in row.cells]) + r" \\")
    lines.append(rules["bottom"])
    return lines


def to_latex(
    table: Table,
    *,
    colours: Sequence[str] = PAPER_COLOURS,
    rules: str | None = None,
    float_env: str = "table*",
    standalone: bool = False,
    portable: bool | None = None,
    fit: bool = False,
) -> str:
    """The table as LaTeX; ``rules`` is "hline" or "booktabs"
    (None: the table's own, `Table.rules`); ``portable`` (default: ``standalone``) leaves out
    multirow and diagbox; ``fit`` shrinks a table wider than the line to the line's width
    (module docstring)."""
    rules = rules or table.rules
    portable = standalone if portable is None else portable
    if rules not in ("hline", "booktabs"):
        raise ValueError(f"rules must be 'hline' or 'booktabs', not {rules!r}")
    rule_set = (
        {"top": r"\hline", "mid": r"\hline", "bottom": r"\hline"}
        if rules == "hline"
        else {"top": r"\toprule", "mid": r"\midrule", "bottom": r"\bottomrule"}
    )
    lines = [
        rf"\begin{{{float_env}}}[t]",
        r"\centering",
        rf"\caption{{{latex_text(table.caption)}}}",
        rf"\label{{{table.name}}}",
        rf"\ifdefined{BOX}\else\newsavebox{{{BOX}}}\fi",
        rf"\sbox{{{BOX}}}{{\resizebox{{{FIT_WIDTH}}}{{!}}{{%" if fit else rf"\sbox{{{BOX}}}{{{{%",
        rf"\begin{{tabular}}{{{_column_spec(table)}}}",
        rule_set["top"],
    ]
    lines += _header_lines(table, rule_set, portable)
    lines += _body_lines(table, colours, rule_set, portable)
    # the notes as wide as the table (at least 60 % of the line), left-aligned under it
    lines += [
        r"\end{tabular}}}",
        rf"\usebox{{{BOX}}}\par\smallskip",
        rf"\parbox{{\ifdim\wd{BOX}<0.6\linewidth "
        rf"0.6\linewidth\else\wd{BOX}\fi}}{{\footnotesize\raggedright",
        rf"Protocol: {latex_text(table.protocol)}.",
    ]
    lines += [rf"\\ {latex_text(note)}" for note in table.footnotes]
    lines += ["}", rf"\end{{{float_env}}}"]
    body = "\n".join(lines) + "\n"
    return standalone_document(body) if standalone else body


def packages_comment() -> str:
    """The comment that opens paper-flavour LaTeX (`olatbench.reports.output.render_tables`): the
    packages its preamble needs and where two of them are."""
    needed = ", ".join(f"\\usepackage{package}" for package in PAPER_PACKAGES)
    return f"% Needs in the preamble: {needed}\n% ({EXTRA_PACKAGES_HINT})\n"


def standalone_document(body: str) -> str:
    """Wrap portable table code in a minimal document that compiles with pdflatex where only
    texlive-latex-recommended is installed (landscape A4, 1 cm margins)."""
    packages = "\n".join(rf"\usepackage{package}" for package in PORTABLE_PACKAGES)
    return (
        r"\documentclass{article}"
        "\n"
        r"\usepackage[margin=1cm,landscape]{geometry}"
        "\n"
        f"{packages}\n\\begin{{document}}\n{body}\\end{{document}}\n"
    )
