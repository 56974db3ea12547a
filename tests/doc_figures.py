"""The figure tables of README.md and docs/*.md, each tied to the command that makes it (pure; the tests use it).

A table of measured figures is written with its command on the line above it:

    <!-- figures: python -m sim.study analyse study -->
    | test | measure | ... |

and the test that runs that command (in a short form) compares the doc's table with the one the command printed:
the same columns and, where they do not depend on the command's arguments, the same rows (the first column's
labels). The figures themselves are not compared: they are one run's noise. So a change in what a command measures
or how it names it cannot leave a stale table behind; `FIGURE_CHECKS` names the test that checks each command, and
tests/unit/test_doc_figures.py holds that every marked table has one.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "DOCS",
    "FIGURE_CHECKS",
    "FigureTable",
    "Table",
    "figure_tables",
    "figures_of",
    "markdown_tables",
    "shape_mismatch",
]

REPO = Path(__file__).resolve().parent.parent
DOCS = (REPO / "README.md", *sorted((REPO / "docs").glob("*.md")))

_MARKER = re.compile(r"^<!--\s*figures:\s*(?P<command>.+?)\s*-->\s*$")
_SEPARATOR = re.compile(r"^\|(\s*:?-+:?\s*\|)+\s*$")

# Each marked table's command, by the words it starts with, and the test that compares its table with what the
# command prints.
FIGURE_CHECKS = {
    "python -m sim.study simulate": "tests/integration/test_study.py",
}


@dataclass(frozen=True)
class Table:
    """A markdown table: its header's cells and its rows' cells, as written; `line` is the header's (1-based)."""

    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    line: int

    @property
    def labels(self) -> tuple[str, ...]:
        """The first column: what each row is."""
        return tuple(row[0] if row else "" for row in self.rows)


@dataclass(frozen=True)
class FigureTable:
    """A doc's table of figures and the command its marker names; `where` is file:line for messages."""

    command: str
    table: Table
    where: str


def _cells(line: str) -> tuple[str, ...]:
    return tuple(cell.strip() for cell in line.strip().strip("|").split("|"))


def markdown_tables(text: str) -> list[Table]:
    """Every table in a markdown text (a header line, a separator line, then rows until a line not starting '|')."""
    lines = text.splitlines()
    tables = []
    i = 0
    while i + 1 < len(lines):
        if lines[i].lstrip().startswith("|") and _SEPARATOR.match(lines[i + 1].strip()):
            header, start = _cells(lines[i]), i + 1
            i += 2
            rows = []
            while i < len(lines) and lines[i].lstrip().startswith("|"):
                rows.append(_cells(lines[i]))
                i += 1
            tables.append(Table(header, tuple(rows), start))
        else:
            i += 1
    return tables


def figure_tables(text: str, source: str) -> list[FigureTable]:
    """The tables of a markdown text that carry a figures marker on the line above; a marker followed by anything
    but a table is a ValueError naming its line."""
    lines = text.splitlines()
    by_line = {table.line: table for table in markdown_tables(text)}
    found = []
    for number, line in enumerate(lines, start=1):
        marker = _MARKER.match(line.strip())
        if marker is None:
            continue
        table = by_line.get(number + 1)
        if table is None:
            raise ValueError(f"{source}:{number}: a figures marker must stand on the line above its table")
        found.append(FigureTable(marker["command"], table, f"{source}:{number}"))
    return found


def figures_of(command_start: str, docs: Iterable[Path] = DOCS) -> list[FigureTable]:
    """The docs' figure tables whose command starts with these words."""
    tables = []
    for path in docs:
        source = path.resolve().relative_to(REPO).as_posix()
        tables += [
            table
            for table in figure_tables(path.read_text(encoding="utf-8"), source)
            if table.command.startswith(command_start)
        ]
    return tables


def shape_mismatch(doc: FigureTable, printed: Sequence[Table], same_rows: bool = True) -> str | None:
    """None when one of the printed tables has the doc table's columns (and, with same_rows, its row labels in
    the same order); otherwise what differs, for an assertion's message."""
    columns = [table for table in printed if table.header == doc.table.header]
    if not columns:
        headers = "; ".join(" | ".join(table.header) for table in printed) or "no table"
        return f"{doc.where}: no printed table has the columns {' | '.join(doc.table.header)} (printed: {headers})"
    if not same_rows or any(table.labels == doc.table.labels for table in columns):
        return None
    return (
        f"{doc.where}: the rows {list(doc.table.labels)} are not the printed {[list(t.labels) for t in columns]}: "
        f"regenerate the table with `{doc.command}`"
    )
