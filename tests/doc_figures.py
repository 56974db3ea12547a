"""The figure tables of README.md and docs/*.md, each tied to the command that makes it (the tests use it), and the
tool that re-measures them.

A table of measured figures is written with its command on the line above it:

    <!-- figures: python -m sim.study analyse study -->
    | test | measure | ... |

and the test that runs that command (in a short form) compares the doc's table with the one the command printed:
the same columns and, where they do not depend on the command's arguments, the same rows (the first column's
labels). The figures themselves are not compared: they are one run's noise. So a change in what a command measures
or how it names it cannot leave a stale table behind; `FIGURE_CHECKS` names the test that checks each command, and
tests/unit/test_doc_figures.py holds that every marked table has one.

Re-measure (each marked command is run, in a scratch directory, and its table rewritten in place):

    .venv/bin/python -m tests.doc_figures --update README.md docs/study.md [--only "python -m bench.endpoint_bench"]

`python` in a command is this interpreter; `$NAME` is taken from the environment (a run that needs one not set is
refused before anything runs), where the tool adds `$REPO` (this repository) and `$PYBULLET_DATA` (pybullet's
robots) when they are not set. Everything but `main` and `_update` is pure.
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import subprocess
import sys
import tempfile
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
    "render",
    "printed_for",
    "replace_table",
    "command_argv",
    "main",
]

REPO = Path(__file__).resolve().parent.parent
DOCS = (REPO / "README.md", *sorted((REPO / "docs").glob("*.md")))

_MARKER = re.compile(r"^<!--\s*figures:\s*(?P<command>.+?)\s*-->\s*$")
_SEPARATOR = re.compile(r"^\|(\s*:?-+:?\s*\|)+\s*$")

# Each marked table's command, by the words it starts with, and the test that compares its table with what the
# command prints.
FIGURE_CHECKS = {
    "python -m sim.study simulate": "tests/integration/test_study.py",
    "python -m sim.trials": "tests/integration/test_trials.py",
    "python -m bench.endpoint_bench": "tests/integration/test_benches.py",
    "python -m bench.freshness_bench": "tests/integration/test_benches.py",
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


def render(table: Table) -> str:
    """A table as markdown lines (no trailing newline)."""
    lines = ["| " + " | ".join(table.header) + " |", "|" + "---|" * len(table.header)]
    return "\n".join(lines + ["| " + " | ".join(row) + " |" for row in table.rows])


def printed_for(doc: FigureTable, printed: Sequence[Table]) -> Table:
    """The printed table that replaces the doc's: the one of its columns and rows, else of its columns, else the only
    one printed (the command's table changed shape); ValueError when none fits or several could."""
    columns = [table for table in printed if table.header == doc.table.header]
    same = [table for table in columns if table.labels == doc.table.labels]
    if same:
        return same[0]
    if len(columns) == 1:
        return columns[0]
    if not columns and len(printed) == 1:
        return printed[0]
    headers = "; ".join(" | ".join(table.header) for table in printed) or "no table"
    raise ValueError(f"{doc.where}: `{doc.command}` printed no table to take its place (printed: {headers})")


def replace_table(text: str, command: str, table: Table) -> str:
    """The markdown text with the table under `command`'s marker replaced by `table`; ValueError when no marker
    names that command."""
    lines = text.splitlines(keepends=True)
    for figures in figure_tables(text, "text"):
        if figures.command == command:
            start = figures.table.line - 1  # the header's index
            end = start + 2 + len(figures.table.rows)
            ending = "\n" if lines[end - 1].endswith("\n") else ""
            return "".join(lines[:start]) + render(table) + ending + "".join(lines[end:])
    raise ValueError(f"no figures marker names `{command}`")


def command_argv(command: str, environ: dict[str, str], python: str) -> list[str]:
    """A marker's command as arguments: `python` is `python`, `$NAME` from `environ`; ValueError naming an unset one."""
    argv = []
    for word in shlex.split(command):
        missing = [name for name in re.findall(r"\$\{?(\w+)\}?", word) if name not in environ]
        if missing:
            raise ValueError(f"`{command}` needs {', '.join(missing)} set in the environment")
        argv.append(re.sub(r"\$\{?(\w+)\}?", lambda m: environ[m[1]], word))
    if argv and argv[0] == "python":
        argv[0] = python
    return argv


def _environ() -> dict[str, str]:
    """The environment commands are run with and expanded from: this one, plus $REPO and $PYBULLET_DATA."""
    import pybullet_data

    return {"REPO": str(REPO), "PYBULLET_DATA": pybullet_data.getDataPath(), **os.environ}


def _update(path: Path, figures: FigureTable) -> None:
    """Run the table's command in a scratch directory and rewrite its table in `path` (read again, so that several
    updates of one file may run side by side)."""
    environ = _environ()
    argv = command_argv(figures.command, environ, sys.executable)
    print(f"{figures.where}: {figures.command}", file=sys.stderr, flush=True)
    environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), environ.get("PYTHONPATH")]))
    with tempfile.TemporaryDirectory(prefix="doc-figures-") as scratch:
        done = subprocess.run(argv, cwd=scratch, env=environ, stdout=subprocess.PIPE, text=True)
    print(done.stdout, end="", flush=True)  # the whole run's output, for its other figures and its verdicts
    if done.returncode != 0:
        raise ValueError(f"{figures.where}: `{figures.command}` exited {done.returncode}")
    table = printed_for(figures, markdown_tables(done.stdout))
    path.write_text(replace_table(path.read_text(encoding="utf-8"), figures.command, table), encoding="utf-8")
    print(f"{figures.where}: rewritten", file=sys.stderr, flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.doc_figures", description=__doc__.splitlines()[0])
    parser.add_argument("--update", nargs="+", type=Path, required=True, metavar="DOC", help="the docs to rewrite")
    parser.add_argument("--only", metavar="COMMAND", help="only the tables whose command starts with these words")
    parser.add_argument("--list", action="store_true", help="name the tables and their commands, run nothing")
    args = parser.parse_args(argv)
    chosen = []
    for path in args.update:
        if not path.is_file():
            parser.error(f"no such doc: {path}")
        for figures in figures_of(args.only or "", (path,)):
            chosen.append((path, figures))
    if not chosen:
        parser.error(
            f"no figure table{' of ' + repr(args.only) if args.only else ''} in {' '.join(map(str, args.update))}"
        )
    if args.list:
        for _, figures in chosen:
            print(f"{figures.where}: {figures.command}")
        return 0
    try:
        for _, figures in chosen:  # every command's variables are there before the first long run starts
            command_argv(figures.command, _environ(), sys.executable)
    except ValueError as error:
        parser.error(str(error))
    for path, figures in chosen:
        try:
            _update(path, figures)
        except ValueError as error:
            print(f"doc_figures: {error}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
