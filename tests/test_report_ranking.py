"""Best / second-best ranking: ties, missing values, lower-is-better metrics, rank sets, printed
precision."""

from __future__ import annotations

import itertools
import random

import pytest

from olatbench.reports.model import Block, Cell, Row, Table
from olatbench.reports.ranking import competition_ranks, rank_table


def brute_force_ranks(values, direction):
    """Rank = 1 + number of others strictly better, by pairwise comparison
    (independent of the implementation)."""
    sign = 1 if direction == "max" else -1
    ranks = []
    for i, value in enumerate(values):
        if value is None:
            ranks.append(None)
            continue
        better = 0
        for j, other in enumerate(values):
            if i != j and other is not None and sign * (other - value) > 0:
                better += 1
        ranks.append(better + 1)
    return ranks


def test_competition_ranks_higher_and_lower_is_better():
    assert competition_ranks([1.0, 3.0, 2.0], "max") == [3, 1, 2]
    assert competition_ranks([1.0, 3.0, 2.0], "min") == [1, 3, 2]


def test_ties_share_a_rank_and_skip_the_next():
    assert competition_ranks([5.0, 5.0, 4.0], "max") == [1, 1, 3]
    assert competition_ranks([6.0, 5.0, 5.0], "max") == [1, 2, 2]


def test_missing_values_are_not_ranked_and_do_not_shift_ranks():
    assert competition_ranks([None, 2.0, None, 1.0], "min") == [None, 2, None, 1]


def test_bad_direction_is_refused():
    with pytest.raises(ValueError, match="direction"):
        competition_ranks([1.0], "up")


def test_competition_ranks_match_brute_force_on_random_inputs():
    generator = random.Random(0)
    for _ in range(200):
        values = [
            generator.choice([None, 0.1, 0.2, 0.3, generator.random()])
            for _ in range(generator.randint(1, 7))
        ]
        for direction in ("max", "min"):
            assert competition_ranks(values, direction) == brute_force_ranks(values, direction)


def _table(rows: list[tuple[str, list[Cell], str | None]], directions: list[str | None]) -> Table:
    columns = [f"c{i}" for i in range(len(directions))]
    return Table(
        "t",
        "caption",
        "protocol",
        ("Method",),
        [[(c, 1) for c in columns]],
        columns,
        [
            Block(
                "PSNR ↑",
                [Row((label,), cells, rank_set) for label, cells, rank_set in rows],
                directions,
            )
        ],
    )


def test_rank_table_keeps_top_two_and_respects_direction_per_column():
    table = _table(
        [
            ("a", [Cell(30.0), Cell(0.10)], "all"),
            ("b", [Cell(31.0), Cell(0.20)], "all"),
            ("c", [Cell(29.0), Cell(0.05)], "all"),
        ],
        ["max", "min"],
    )
    rank_table(table)
    ranks = [[cell.rank for cell in row.cells] for row in table.blocks[0].rows]
    assert ranks == [[2, 2], [1, None], [None, 1]]


def test_rank_sets_are_ranked_separately_and_none_is_never_ranked():
    table = _table(
        [
            ("A", [Cell(1.0)], "comp"),
            ("B", [Cell(2.0)], "comp"),
            ("H", [Cell(0.5)], "sched"),
            ("I", [Cell(0.7)], "sched"),
            ("paper", [Cell(99.0)], None),
        ],
        ["max"],
    )
    rank_table(table, top=1)
    assert [row.cells[0].rank for row in table.blocks[0].rows] == [None, 1, None, 1, None]


def test_values_compare_as_printed():
    """0.05061 and 0.05059 both print as 0.0506: they tie."""
    table = _table(
        [("a", [Cell(0.05061)], "all"), ("b", [Cell(0.05059)], "all"), ("c", [Cell(0.04)], "all")],
        ["min"],
    )
    rank_table(table)
    assert [row.cells[0].rank for row in table.blocks[0].rows] == [2, 2, 1]


def test_missing_text_and_nan_cells_are_skipped_and_min_values_applies():
    table = _table(
        [
            ("a", [Cell(None)], "all"),
            ("b", [Cell("RTX 4090")], "all"),
            ("c", [Cell(float("nan"))], "all"),
            ("d", [Cell(3.0)], "all"),
        ],
        ["max"],
    )
    rank_table(table, min_values=2)  # one number only: not ranked
    assert all(row.cells[0].rank is None for row in table.blocks[0].rows)
    rank_table(table, min_values=1)
    assert table.blocks[0].rows[3].cells[0].rank == 1


def test_columns_filter_and_unranked_directions():
    table = _table(
        [("a", [Cell(1.0), Cell(1.0)], "all"), ("b", [Cell(2.0), Cell(2.0)], "all")], ["max", None]
    )
    rank_table(table, columns=lambda name: name == "c1")
    assert all(cell.rank is None for row in table.blocks[0].rows for cell in row.cells)


@pytest.mark.parametrize("order", list(itertools.permutations(range(3))))
def test_ranking_does_not_depend_on_row_order(order):
    values = [30.0, 31.0, 31.0]
    rows = [(str(i), [Cell(values[i])], "all") for i in order]
    table = _table(rows, ["max"])
    rank_table(table)
    ranks = {row.labels[0]: row.cells[0].rank for row in table.blocks[0].rows}
    assert ranks == {"0": None, "1": 1, "2": 1}
