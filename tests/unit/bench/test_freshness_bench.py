"""README's freshness table (`bench.freshness_bench --markdown`): per topic, each side's arrivals and ages."""

from __future__ import annotations

from bench.freshness_bench import DOWN, ORIGINAL, Bars, Received, down_table
from tests.doc_figures import markdown_tables

BARS = Bars(image_s=0.0737, buffer_s=0.0052, delay_s=0.008)
MS = 1_000_000  # ns


def arrivals(count: int, period_ms: float, age_ms: float, creep_ms: float = 0.0) -> list[tuple[int, int]]:
    """`count` arrivals `period_ms` apart, each `age_ms` old plus `creep_ms` more per second run."""
    return [(int(k * period_ms * MS), int((age_ms + creep_ms * k * period_ms / 1000) * MS)) for k in range(count)]


def test_each_side_gives_its_counts_and_ages_and_a_side_that_did_not_run_says_so() -> None:
    ours = {topic: Received(kind, sent=100) for kind, topic, _ in DOWN}
    ours["/fresh/image"].arrivals = arrivals(25, 80.0, 115.0)  # 12.5 Hz over 1.92 s
    ours["/fresh/joint_states"].arrivals = arrivals(100, 10.0, 58.0)
    ours["/fresh/tf"].arrivals = arrivals(99, 10.0, 58.0)
    theirs = {topic: Received(kind, sent=100) for kind, topic, _ in DOWN}
    theirs["/fresh/image"].arrivals = arrivals(400, 80.0, 3000.0, creep_ms=1000.0)  # older by a second a second
    (table,) = markdown_tables(down_table([("this tree", ours), (ORIGINAL, theirs), ("another", None)], BARS))
    assert table.header == (
        "topic",
        "this tree: received, age p50 / p99",
        "Unity's original: received, age p50 / p99",
        "another: received, age p50 / p99",
        "bar (p99)",
    )
    rows = {row[0]: row[1:] for row in table.rows}
    assert rows["image"][0] == "12.5 Hz, 115 / 115 ms" and rows["image"][2:] == ("not run", "194 ms")
    assert rows["joint_states"][0] == "100/100, 58 / 58 ms" and rows["tf"][0] == "99/100, 58 / 58 ms"
    assert rows["joint_states"][1] == "0/100" and rows["joint_states"][3] == "105 ms"
    # the original's image ages creep: its first and last 10 s, in seconds once past one
    first, last = rows["image age p50, first / last 10 s"][1].removesuffix(" s").split(" / ")
    assert float(first) < 10.0 < float(last)
    assert rows["image age p50, first / last 10 s"][0] == "115 / 115 ms"
