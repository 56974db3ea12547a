"""The endpoint bench's tables: one endpoint's rows with their verdicts, and the A/B comparison that past notes
compare by row name (rows of one name, such as "  endpoint CPU", matched by their order)."""

from __future__ import annotations

import pytest

from bench.endpoint_bench.records import Row
from bench.endpoint_bench.tables import compare_tables, leading_number, occurrences, print_table


@pytest.mark.parametrize(
    "cell, number",
    [("1,234.5 [1,100.0-1,300.0]", 1234.5), ("0.27/2.76/4.02", None), ("90/90", None), ("yes", None), ("", None)],
)
def test_a_cells_leading_number(cell: str, number: float | None) -> None:
    assert leading_number(cell) == number


def test_rows_of_one_name_are_told_apart_by_their_order() -> None:
    rows = [Row("a", "1"), Row("  cpu", "2"), Row("b", "3"), Row("  cpu", "4")]
    assert occurrences(rows) == [("a", 0), ("  cpu", 0), ("b", 0), ("  cpu", 1)]


def test_the_table_shows_each_rows_verdict_and_counts_the_targets_met(capsys: pytest.CaptureFixture[str]) -> None:
    print_table([Row("rate", "10", ok=True), Row("gap", "99", target="< 50", ok=False), Row("info", "x")], "HEADER")
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "HEADER" and lines[-1] == "1/2 targets met"
    assert lines[4].split() == ["rate", "10", "PASS"] and lines[5].split() == ["gap", "99", "<", "50", "MISS"]
    assert lines[6].split() == ["info", "x"]


def test_the_comparison_divides_this_trees_figures_by_the_others_row_by_row(
    capsys: pytest.CaptureFixture[str],
) -> None:
    ours = [Row("rate", "200 [190-210]"), Row("  cpu", "0.5"), Row("  cpu", "3"), Row("alive", "yes")]
    theirs = [Row("rate", "100"), Row("  cpu", "1.0"), Row("  cpu", "0"), Row("new in ours only", "1")]
    compare_tables(ours, theirs, "this tree", "abc123")
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("A/B: this tree against abc123")
    table = [line.split() for line in lines[4:8]]
    assert table == [
        ["rate", "200", "[190-210]", "100", "2.00"],
        ["cpu", "0.5", "1.0", "0.50"],
        ["cpu", "3", "0"],
        ["alive", "yes"],
    ]
