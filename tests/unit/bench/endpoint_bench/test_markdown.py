"""README's tables of the endpoint bench (`--markdown`): built from the rows the phases record, by their names."""

from __future__ import annotations

from bench.endpoint_bench.markdown import markdown, performance_table, websocket_table
from bench.endpoint_bench.records import Row
from tests.doc_figures import markdown_tables

# rows as the throughput, large and websocket phases name them, with their figures' formats
PHASE_ROWS = [
    Row("TCP->ROS [msg/s] vs rospy sync publisher", "352,104 [340k-360k]", "360,000", "0.98"),
    Row("ROS->TCP [msg/s], sync source, vs rospy sync", "212,300", "230,000", "0.92"),
    Row("Image 2.7 MB TCP->ROS [msg/s] vs rospy sync publisher, same rospy subscriber", "454.2 [440.0-460.1]", "452.0"),
    Row("  endpoint CPU s / 100 msgs", "0.090"),
    Row("Image 2.7 MB ROS->TCP (q 10 source) [msg/s] vs raw TCPROS reader, same source", "682.4", "1337.0", "0.51"),
    Row(
        "PointCloud2 1 MiB TCP->ROS [msg/s] vs rospy sync publisher, same rospy subscriber", "1190.3", "1167.2", "1.02"
    ),
    Row("PointCloud2 1 MiB ROS->TCP (q 10 source) [msg/s] vs raw TCPROS reader, same source", "2586", "3593", "0.72"),
    Row("1 MiB round trip @ 30 Hz p50 [ms]", "2.44", "1.88", "1.30"),
    Row("1 MiB round trip @ 30 Hz max [ms]", "6.02", "3.61", "1.67"),
    Row("  endpoint CPU during the round trips [% of a core]", "3.1"),
    Row("Endpoint RSS right after the large messages [MiB]", "54.3"),
    Row("WebSocket JointState client->ROS [msg/s] vs TCP client", "103,000", "357,000", "0.29"),
    Row("  endpoint CPU s / 10,000 msgs, WebSocket vs TCP", "0.094", "0.026"),
    Row("WebSocket Image 2.7 MB ROS->client [msg/s] vs TCP client", "314.2", "652.0", "0.48"),
    Row("  endpoint CPU s / 100 msgs, WebSocket vs TCP", "0.190", "0.100"),
]


def test_the_performance_table_takes_each_figure_from_its_phases_row() -> None:
    (table,) = markdown_tables(performance_table(PHASE_ROWS, PHASE_ROWS[:2]))
    assert table.header == ("path", "this tree", "reference", "ratio", "--ab revision")
    rows = {row[0]: row[1:] for row in table.rows}
    assert rows["Image 2.7 MB TCP->ROS [msg/s]"] == (
        "454",
        "452 (rospy publisher, same subscriber)",
        "",
        "not measured",
    )
    assert rows["PointCloud2 1 MiB ROS->TCP, q 10 source [msg/s]"][:3] == (
        "2586",
        "3593 (raw TCPROS reader, same source)",
        "0.72",
    )
    assert rows["1 MiB round trip at 30 Hz, p50 / max [ms]"][:3] == (
        "2.44 / 6.0",
        "1.88 / 3.6 (rospy alone)",
        "1.30 / 1.67",
    )
    assert rows["endpoint CPU during that round trip"][0] == "3.1 %"
    assert rows["endpoint RSS after the large messages [MiB]"][0] == "54"
    # the other revision ran only the throughput phase here
    assert rows["small JointState flood, TCP->ROS [msg/s]"] == ("352k", "", "", "352k")
    assert rows["small JointState flood, ROS->TCP [msg/s]"] == ("212k", "", "", "212k")


def test_the_websocket_table_gives_rates_and_cpu_per_message_in_its_unit() -> None:
    (table,) = markdown_tables(websocket_table(PHASE_ROWS))
    rows = {row[0]: row[1:] for row in table.rows}
    assert rows["JointState client->ROS"] == ("103k", "357k", "0.29", "9.4 / 2.6 µs")
    assert rows["Image 2.7 MB ROS->client"] == ("314", "652", "0.48", "1.9 / 1.0 ms")
    assert rows["JointState ROS->client"] == ("not measured", "not measured", "", "")


def test_without_the_phases_every_figure_reads_not_measured_in_the_same_shape() -> None:
    full, empty = markdown_tables(markdown(PHASE_ROWS)), markdown_tables(markdown([]))
    assert [(t.header, t.labels) for t in full] == [(t.header, t.labels) for t in empty]
    assert all(row[1] == "not measured" for table in empty for row in table.rows)
    assert all(row[4] == "not run" for row in full[0].rows)
