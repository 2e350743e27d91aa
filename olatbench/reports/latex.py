"""LaTeX for a `Table` in the paper's style: diagbox corner, multirow/multicolumn headers, metric
blocks, best / second-best cells as ``\\cellcolor[rgb]{1,0.8,0.8}`` / ``{1,0.9,0.8}``.

Strings in the model are plain text; `latex_text` escapes them and turns the few symbols the
tables use (↑ ↓ ± — ≈ < >, "GS3") into LaTeX; the en-dash "–" stays as the paper's source writes it
(``E: Full – S``; pdflatex reads UTF-8). ``standalone=True`` wraps the table in a
minimal document that compiles with pdflatex (packages: xcolor[table], colortbl, multirow, diagbox,
booktabs, graphicx).
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from olatbench.reports.model import Cell, Table

PAPER_COLOURS = ("1,0.8,0.8", "1,0.9,0.8")  # best (red), second best (orange), as rgb in [0, 1]
PACKAGES = ("[table]{xcolor}", "{colortbl}", "{multirow}", "{diagbox}", "{booktabs}", "{graphicx}")

_ESCAPES = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
            "{": r"\{", "}": r"\}", "^": r"\^{}", "~": r"\textasciitilde{}", "↑": r"$\uparrow$", "↓": r"$\downarrow$",
            "±": r"$\pm$", "—": "---", "≈": r"$\approx$", "<": r"$<$", ">": r"$>$", "Δ": r"$\Delta$",
            "−": r"$-$", "×": r"$\times$"}


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


def _header_lines(table: Table, rules: dict[str, str]) -> list[str]:
    levels = len(table.header)
    labels = len(table.label_names)
    corner = rf"\diagbox{{{latex_text(table.corner[0])}}}{{{latex_text(table.corner[1])}}}"
    if levels > 1:
        corner = rf"\multirow{{{levels}}}{{*}}{{{corner}}}"
    if labels > 1:
        corner = rf"\multicolumn{{{labels}}}{{c|}}{{{corner}}}"
    lines = []
    first_column = labels + 1
    for level, header_row in enumerate(table.header):
        parts = [corner if level == 0 else ("" if labels == 1 else rf"\multicolumn{{{labels}}}{{c|}}{{}}")]
        position = 0
        for title, span in header_row:
            position += span
            bar = "|" if position - 1 in table.column_rules else ""
            # single columns take their rule from the column spec; spans need their own
            parts.append(rf"\multicolumn{{{span}}}{{c{bar}}}{{{latex_text(title)}}}" if span > 1
                         else latex_text(title))
        lines.append(" & ".join(parts) + r" \\")
        if level < levels - 1:
            lines.append(rf"\cline{{{first_column}-{labels + len(table.columns)}}}")
    lines.append(rules["mid"])
    return lines


def _body_lines(table: Table, colours: Sequence[str], rules: dict[str, str]) -> list[str]:
    width = len(table.label_names) + len(table.columns)
    lines = []
    for number, block in enumerate(table.blocks):
        if number > 0:
            lines.append(rules["mid"])
        if block.title is not None:
            lines += [rf"\multicolumn{{{width}}}{{c}}{{{_block_title(block.title)}}} \\", rules["mid"]]
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
                    span = sum(1 for later in block.rows[index:] if later.labels[0] == row.labels[0])
                    labels[0] = rf"\multirow{{{span}}}{{*}}{{{latex_text(row.labels[0])}}}" if span > 1 \
                        else latex_text(row.labels[0])
                previous = row.labels[0]
                labels[1:] = [latex_text(label) for label in labels[1:]]
            else:
                labels = [latex_text(label) for label in labels]
            lines.append(" & ".join(labels + [_cell(cell, colours) for cell in row.cells]) + r" \\")
    lines.append(rules["bottom"])
    return lines


def to_latex(table: Table, *, colours: Sequence[str] = PAPER_COLOURS, rules: str | None = None,
             float_env: str = "table*", standalone: bool = False) -> str:
    """The table as LaTeX; ``rules`` is "hline" or "booktabs" (None: the table's own, `Table.rules`)."""
    rules = rules or table.rules
    if rules not in ("hline", "booktabs"):
        raise ValueError(f"rules must be 'hline' or 'booktabs', not {rules!r}")
    rule_set = ({"top": r"\hline", "mid": r"\hline", "bottom": r"\hline"} if rules == "hline"
                else {"top": r"\toprule", "mid": r"\midrule", "bottom": r"\bottomrule"})
    lines = [rf"\begin{{{float_env}}}[t]", r"\centering",
             rf"\caption{{{latex_text(table.caption)}}}", rf"\label{{{table.name}}}",
             r"\resizebox{\linewidth}{!}{%", rf"\begin{{tabular}}{{{_column_spec(table)}}}", rule_set["top"]]
    lines += _header_lines(table, rule_set)
    lines += _body_lines(table, colours, rule_set)
    lines += [r"\end{tabular}}", r"\par\smallskip{\footnotesize", rf"Protocol: {latex_text(table.protocol)}."]
    lines += [rf"\\ {latex_text(note)}" for note in table.footnotes]
    lines += ["}", rf"\end{{{float_env}}}"]
    body = "\n".join(lines) + "\n"
    return standalone_document(body) if standalone else body


def standalone_document(body: str) -> str:
    """Wrap table code in a minimal compilable document (landscape-wide page)."""
    packages = "\n".join(rf"\usepackage{package}" for package in PACKAGES)
    return (r"\documentclass{article}" "\n" r"\usepackage[margin=1cm,landscape]{geometry}" "\n"
            f"{packages}\n\\begin{{document}}\n{body}\\end{{document}}\n")
