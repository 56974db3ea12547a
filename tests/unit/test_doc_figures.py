"""The docs' figure tables (tests/doc_figures.py): how they are read and compared, and that each is checked."""

from __future__ import annotations

import pytest

from tests.doc_figures import (
    DOCS,
    FIGURE_CHECKS,
    REPO,
    FigureTable,
    Table,
    figure_tables,
    markdown_tables,
    shape_mismatch,
)

DOC = """Some text.

<!-- figures: python -m bench.x --long -->
| path | ours | ratio |
|---|---|---|
| images | 12 | 1.00 |
| points | 9 | 0.98 |

| reference | only |
|:--|--:|
| a | b |
"""


def test_tables_are_read_with_their_header_rows_and_line() -> None:
    first, second = markdown_tables(DOC)
    assert first == Table(("path", "ours", "ratio"), (("images", "12", "1.00"), ("points", "9", "0.98")), 4)
    assert first.labels == ("images", "points")
    assert second.header == ("reference", "only") and second.rows == (("a", "b"),)


def test_only_a_marked_table_is_a_figure_table() -> None:
    (figures,) = figure_tables(DOC, "doc.md")
    assert figures.command == "python -m bench.x --long" and figures.where == "doc.md:3"
    assert figures.table.header == ("path", "ours", "ratio")


def test_a_marker_away_from_its_table_is_an_error() -> None:
    with pytest.raises(ValueError, match="doc.md:1: a figures marker must stand on the line above its table"):
        figure_tables("<!-- figures: python -m x -->\n\n| a |\n|---|\n| 1 |\n", "doc.md")


def test_the_shape_is_compared_not_the_figures() -> None:
    (doc,) = figure_tables(DOC, "doc.md")
    printed = markdown_tables("| path | ours | ratio |\n|---|---|---|\n| images | 99 | 0.5 |\n| points | 1 | 7 |\n")
    assert shape_mismatch(doc, printed) is None


def test_a_renamed_column_or_row_is_a_stale_table() -> None:
    (doc,) = figure_tables(DOC, "doc.md")
    renamed = markdown_tables("| path | this tree | ratio |\n|---|---|---|\n| images | 1 | 1 |\n| points | 1 | 1 |\n")
    assert "no printed table has the columns path | ours | ratio" in str(shape_mismatch(doc, renamed))
    row_gone = markdown_tables("| path | ours | ratio |\n|---|---|---|\n| images | 1 | 1 |\n")
    message = str(shape_mismatch(doc, row_gone))
    assert "the rows ['images', 'points'] are not the printed [['images']]" in message
    assert "regenerate the table with `python -m bench.x --long`" in message
    # rows that follow the command's arguments (robots in a campaign, say) are compared by columns only
    assert shape_mismatch(doc, row_gone, same_rows=False) is None


def _all_figure_tables() -> list[FigureTable]:
    tables = []
    for path in DOCS:
        tables += figure_tables(path.read_text(encoding="utf-8"), path.relative_to(REPO).as_posix())
    return tables


def test_every_figure_table_in_the_docs_is_checked_against_its_command() -> None:
    tables = _all_figure_tables()
    assert tables, "README.md and docs/ have figure tables"
    for figures in tables:
        checks = [start for start in FIGURE_CHECKS if figures.command.startswith(start)]
        assert checks, f"{figures.where}: no test compares `{figures.command}`'s table (tests/doc_figures.py)"
        for start in checks:
            test = REPO / FIGURE_CHECKS[start]
            assert "figures_of(" in test.read_text(encoding="utf-8"), f"{test} compares no doc table"
