"""README's tables of the endpoint's figures as markdown, from the rows the phases recorded (pure): what `--markdown`
prints, and tests/doc_figures.py compares with README's (same rows and columns).

The performance table's figures come from the throughput and large phases, the WebSocket table's from the websocket
phase; a figure whose row the run did not record reads "not measured" (a phase that did not run, or a row renamed
in a phase: it shows, rather than a stale figure).
"""

from __future__ import annotations

from collections.abc import Sequence

from bench.endpoint_bench.large import LARGE_KINDS, LARGE_RTT_HZ
from bench.endpoint_bench.records import Row
from bench.endpoint_bench.settings import LARGE_ROS_QUEUE
from bench.endpoint_bench.tables import leading_number

__all__ = ["NOT_MEASURED", "performance_table", "websocket_table", "markdown"]

NOT_MEASURED = "not measured"
AB_COLUMN = "--ab revision"  # its figures, or "not run" without --ab


def _row(rows: Sequence[Row], name_start: str) -> Row | None:
    return next((row for row in rows if row.name.startswith(name_start)), None)


def _number(text: str) -> float | None:
    return leading_number(text) if text else None


def _rate(value: float | None) -> str:
    """A message rate as README writes it: thousands as "352k", else whole messages."""
    if value is None:
        return NOT_MEASURED
    return f"{value / 1000:.0f}k" if value >= 10_000 else f"{value:.0f}"


def _large(rows: Sequence[Row], name_start: str, reference_label: str) -> tuple[str, str, str]:
    row = _row(rows, name_start)
    if row is None:
        return NOT_MEASURED, "", ""
    return _rate(_number(row.value)), f"{_rate(_number(row.ceiling))} ({reference_label})", row.ratio


def _round_trip(rows: Sequence[Row]) -> tuple[str, str, str]:
    p50, most = (_row(rows, f"1 MiB round trip @ {LARGE_RTT_HZ} Hz {label} [ms]") for label in ("p50", "max"))
    if p50 is None or most is None:
        return NOT_MEASURED, "", ""
    figures = [_number(text) for text in (p50.value, most.value, p50.ceiling, most.ceiling)]
    if any(figure is None for figure in figures):
        return NOT_MEASURED, "", ""
    ours_p50, ours_max, their_p50, their_max = (float(figure or 0.0) for figure in figures)
    reference = f"{their_p50:.2f} / {their_max:.1f} (rospy alone)"
    return f"{ours_p50:.2f} / {ours_max:.1f}", reference, f"{p50.ratio} / {most.ratio}"


def _single(rows: Sequence[Row], name_start: str, spec: str) -> str:
    row = _row(rows, name_start)
    value = None if row is None else _number(row.value)
    return NOT_MEASURED if value is None else spec.format(value)


def _flood(rows: Sequence[Row], name_start: str) -> str:
    row = _row(rows, name_start)
    return _rate(None if row is None else _number(row.value))


def _performance_cells(rows: Sequence[Row]) -> list[tuple[str, str, str, str]]:
    """(path, figure, reference, ratio) per README row."""
    cells = []
    for _, label in LARGE_KINDS:
        into_ros = _large(rows, f"{label} TCP->ROS [msg/s] vs ", "rospy publisher, same subscriber")
        cells.append((f"{label} TCP->ROS [msg/s]", *into_ros))
        cells.append(
            (
                f"{label} ROS->TCP, q {LARGE_ROS_QUEUE} source [msg/s]",
                *_large(
                    rows,
                    f"{label} ROS->TCP (q {LARGE_ROS_QUEUE} source) [msg/s] vs ",
                    "raw TCPROS reader, same source",
                ),
            )
        )
    cells.append((f"1 MiB round trip at {LARGE_RTT_HZ} Hz, p50 / max [ms]", *_round_trip(rows)))
    cpu = _single(rows, "  endpoint CPU during the round trips [% of a core]", "{:.1f} %")
    cells.append(("endpoint CPU during that round trip", cpu, "", ""))
    rss = _single(rows, "Endpoint RSS right after the large messages [MiB]", "{:.0f}")
    cells.append(("endpoint RSS after the large messages [MiB]", rss, "", ""))
    cells.append(("small JointState flood, TCP->ROS [msg/s]", _flood(rows, "TCP->ROS [msg/s] vs rospy "), "", ""))
    cells.append(
        ("small JointState flood, ROS->TCP [msg/s]", _flood(rows, "ROS->TCP [msg/s], sync source, vs rospy "), "", "")
    )
    return cells


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return "\n".join(lines + ["| " + " | ".join(row) + " |" for row in rows])


def performance_table(ours: Sequence[Row], theirs: Sequence[Row] | None = None) -> str:
    """README's performance table: this tree's large-message, round-trip, memory and flood figures beside their
    references, and the other revision's of `--ab` in the last column ("not run" without it)."""
    header = ["path", "this tree", "reference", "ratio", AB_COLUMN]
    other = _performance_cells(theirs) if theirs is not None else []
    table = []
    for k, (path, figure, reference, ratio) in enumerate(_performance_cells(ours)):
        table.append([path, figure, reference, ratio, other[k][1] if theirs is not None else "not run"])
    return _table(header, table)


def websocket_table(rows: Sequence[Row]) -> str:
    """README's WebSocket table: each flow through a WebSocket client and a TCP client, and the endpoint's CPU per
    message of each (µs for JointState, ms for the image)."""
    table = []
    for label, cpu_unit, per_unit in (("JointState", "µs", 1e6 / 1e4), ("Image 2.7 MB", "ms", 1e3 / 100)):
        for direction in ("client->ROS", "ROS->client"):
            name = f"WebSocket {label} {direction} [msg/s] vs TCP client"
            index = next((k for k, row in enumerate(rows) if row.name == name), None)
            if index is None or index + 1 >= len(rows):
                table.append([f"{label} {direction}", NOT_MEASURED, NOT_MEASURED, "", ""])
                continue
            flow, cpu = rows[index], rows[index + 1]
            ws_cpu, tcp_cpu = _number(cpu.value), _number(cpu.ceiling)
            cpu_cell = (
                f"{ws_cpu * per_unit:.1f} / {tcp_cpu * per_unit:.1f} {cpu_unit}"
                if ws_cpu is not None and tcp_cpu is not None
                else NOT_MEASURED
            )
            table.append(
                [
                    f"{label} {direction}",
                    _rate(_number(flow.value)),
                    _rate(_number(flow.ceiling)),
                    flow.ratio,
                    cpu_cell,
                ]
            )
    header = ["path", "WebSocket [msg/s]", "TCP [msg/s]", "ratio", "endpoint CPU per message, WebSocket / TCP"]
    return _table(header, table)


def markdown(ours: Sequence[Row], theirs: Sequence[Row] | None = None) -> str:
    """Both tables, one after the other; the figures of phases that did not run read "not measured"."""
    return performance_table(ours, theirs) + "\n\n" + websocket_table(ours)
