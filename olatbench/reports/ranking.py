"""Best / second-best cells: competition ranking per column among rows of the same rank set.

Rules (the paper's colouring, made explicit):

* values are compared as printed (rounded to the cell's decimals), so two cells that read the
  same share a rank: 1, 2, 2 colours both tied cells as second best;
* competition ("min") ranking: a cell's rank is 1 + the number of strictly better cells, so a tie
  for best leaves no second best (1, 1, 3);
* missing cells ("—") and text cells are never ranked and never shift a rank;
* a column of a rank set is ranked only when at least ``min_values`` cells hold numbers;
* only ranks up to ``top`` (2: best and second best; 1: best only) are kept.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable, Sequence

from olatbench.reports.model import Cell, Table


def competition_ranks(values: Sequence[float | None], direction: str) -> list[int | None]:
    """Rank numbers (None = missing, unranked): 1 + the count of strictly better values.

    ``direction`` is "max" (higher is better) or "min" (lower is better).
    """
    if direction not in ("max", "min"):
        raise ValueError(f"direction must be 'max' or 'min', not {direction!r}")
    present = [value for value in values if value is not None]
    ranks: list[int | None] = []
    for value in values:
        if value is None:
            ranks.append(None)
        elif direction == "max":
            ranks.append(1 + sum(other > value for other in present))
        else:
            ranks.append(1 + sum(other < value for other in present))
    return ranks


def _printed(cell: Cell) -> float | None:
    number = cell.number
    return None if number is None else round(number, cell.decimals)


def rank_table(
    table: Table, top: int = 2, min_values: int = 2, columns: Callable[[str], bool] | None = None
) -> Table:
    """Set ``Cell.rank`` (1..top or None) on every cell of ``table`` in place; returns the table.

    ``columns`` selects which leaf columns are ranked (by name; default all with a direction).
    """
    if top < 1:
        raise ValueError("top must be at least 1")
    for block in table.blocks:
        sets: dict[str, list[int]] = defaultdict(list)
        for index, row in enumerate(block.rows):
            for cell in row.cells:
                cell.rank = None
            if row.rank_set is not None:
                sets[row.rank_set].append(index)
        for column, direction in enumerate(block.directions):
            if direction is None or (columns is not None and not columns(table.columns[column])):
                continue
            for members in sets.values():
                cells = [block.rows[index].cells[column] for index in members]
                values = [_printed(cell) for cell in cells]
                if sum(value is not None for value in values) < min_values:
                    continue
                for cell, rank in zip(cells, competition_ranks(values, direction), strict=True):
                    cell.rank = rank if rank is not None and rank <= top else None
    return table
