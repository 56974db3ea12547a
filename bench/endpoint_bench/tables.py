"""The benchmark's table (one endpoint's rows with their verdicts) and the A/B comparison of two endpoints' rows."""

from __future__ import annotations

from bench.endpoint_bench.records import Row


def print_table(rows: list[Row], header: str) -> None:
    columns = ("measurement", "endpoint", "reference (named in the row)", "ratio", "target", "result")
    cells = [
        (r.name, r.value, r.ceiling, r.ratio, r.target, "" if r.ok is None else "PASS" if r.ok else "MISS")
        for r in rows
    ]
    widths = [max(len(c[i]) for c in [columns, *cells]) for i in range(len(columns))]
    line = "  ".join("-" * w for w in widths)
    print(header)
    print(line)
    print("  ".join(c.ljust(w) for c, w in zip(columns, widths)))
    print(line)
    for c in cells:
        print("  ".join(v.ljust(w) for v, w in zip(c, widths)).rstrip())
    print(line)
    verdicts = [r.ok for r in rows if r.ok is not None]
    print(f"{sum(verdicts)}/{len(verdicts)} targets met")


def compare_tables(ours: list[Row], theirs: list[Row], our_name: str, their_name: str) -> None:
    """The rows of both endpoints side by side, with the ratio of their leading numbers (ours / theirs)."""
    their_values = dict(zip(occurrences(theirs), (row.value for row in theirs)))
    columns = ("measurement", our_name, their_name, "ratio")
    cells = []
    for key, row in zip(occurrences(ours), ours):
        other = their_values.get(key, "")
        a, b = leading_number(row.value), leading_number(other)
        ratio = f"{a / b:.2f}" if a is not None and b else ""
        cells.append((row.name, row.value, other, ratio))
    widths = [max(len(c[i]) for c in [columns, *cells]) for i in range(len(columns))]
    line = "  ".join("-" * w for w in widths)

    def show(values: tuple[str, ...]) -> None:
        print("  ".join(v.ljust(w) for v, w in zip(values, widths)).rstrip())

    print(f"A/B: {our_name} against {their_name}, phase by phase on one roscore (ratio = {our_name} / {their_name})")
    print(line)
    show(columns)
    print(line)
    for values in cells:
        show(values)
    print(line)


def occurrences(rows: list[Row]) -> list[tuple[str, int]]:
    """Each row's name with how many rows of that name came before it (rows such as "  endpoint CPU" repeat)."""
    seen: dict[str, int] = {}
    keys = []
    for row in rows:
        keys.append((row.name, seen.get(row.name, 0)))
        seen[row.name] = keys[-1][1] + 1
    return keys


def leading_number(text: str) -> float | None:
    """The number a cell starts with ("1,234.5 [..]" -> 1234.5); None when it starts with none or is a count of a
    count ("90/90")."""
    token = text.split(" ", 1)[0].replace(",", "")
    try:
        return float(token)
    except ValueError:
        return None
