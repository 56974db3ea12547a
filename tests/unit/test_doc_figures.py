"""The docs' figure tables (tests/doc_figures.py): how they are read and compared, and that each is checked."""

from __future__ import annotations

import pytest

from tests.doc_figures import (
    DOCS,
    FIGURE_CHECKS,
    REPO,
    FigureTable,
    Table,
    command_argv,
    figure_tables,
    markdown_tables,
    printed_for,
    replace_table,
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


def test_a_table_is_rewritten_in_place_with_what_its_command_printed() -> None:
    printed = markdown_tables("| path | ours | ratio |\n|---|---|---|\n| images | 13 | 1.01 |\n| clouds | 8 | 0.9 |\n")
    rewritten = replace_table(DOC, "python -m bench.x --long", printed[0])
    assert rewritten == DOC.replace(
        "| path | ours | ratio |\n|---|---|---|\n| images | 12 | 1.00 |\n| points | 9 | 0.98 |\n",
        "| path | ours | ratio |\n|---|---|---|\n| images | 13 | 1.01 |\n| clouds | 8 | 0.9 |\n",
    )
    assert figure_tables(rewritten, "doc.md")[0].table.rows == printed[0].rows
    with pytest.raises(ValueError, match="no figures marker names `python -m other`"):
        replace_table(DOC, "python -m other", printed[0])


def test_the_printed_table_taken_is_the_one_of_the_docs_shape_else_its_columns_else_the_only_one() -> None:
    (doc,) = figure_tables(DOC, "doc.md")
    other = Table(("a", "b"), (("1", "2"),), 1)
    same_columns = Table(("path", "ours", "ratio"), (("images", "1", "1"),), 1)
    same_shape = Table(("path", "ours", "ratio"), (("images", "1", "1"), ("points", "2", "2")), 1)
    assert printed_for(doc, [other, same_columns, same_shape]) == same_shape
    assert printed_for(doc, [other, same_columns]) == same_columns
    assert printed_for(doc, [other]) == other  # the command's table changed shape: the new one replaces it
    with pytest.raises(ValueError, match="doc.md:3: `python -m bench.x --long` printed no table to take its place"):
        printed_for(doc, [other, other])


def test_a_command_runs_on_this_python_with_its_variables_from_the_environment() -> None:
    argv = command_argv("python -m x --robot $DATA/arm.urdf --out 'a b'", {"DATA": "/d"}, "/venv/python")
    assert argv == ["/venv/python", "-m", "x", "--robot", "/d/arm.urdf", "--out", "a b"]
    with pytest.raises(ValueError, match="needs UNSET set in the environment"):
        command_argv("python -m x --original ${UNSET}", {}, "/venv/python")


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
