"""bridge.diagnostics, pure: the statuses of the endpoint, its clients and topics; the client times of __ping."""

from __future__ import annotations

from datetime import datetime, timezone

import pytest

from bridge.diagnostics import OK, WARN, ClientSnapshot, TopicSnapshot, parse_client_time, report


def client(**changes: object) -> ClientSnapshot:
    fields = dict(
        name="#1 127.0.0.1:50000",
        connected_at=1000.0,
        authenticated=True,
        frames_in=10,
        frames_out=20,
        bytes_in=300,
        bytes_out=400,
        queued_frames=0,
        queue_capacity=1024,
        oldest_queued_age_s=None,
        dropped_out=0,
        dropped_in=0,
        pings=1,
        ping_clock_offset_s=0.25,
        ping_round_trip_s=None,
    )
    fields.update(changes)
    return ClientSnapshot(**fields)  # type: ignore[arg-type]


def values(status) -> dict:
    return dict(status.values)


def test_one_status_for_the_endpoint_each_client_and_each_topic() -> None:
    topic = TopicSnapshot(
        "/joint_states",
        "sensor_msgs/JointState",
        2,
        1,
        to_clients=500,
        from_clients=100,
        ros_publishers=1,
        ros_subscribers=3,
    )
    statuses, counts = report("/ep", "127.0.0.1:10000", 1010.0, [client()], [topic], {}, 1.0)
    assert [s.name for s in statuses] == ["/ep: endpoint", "/ep: client #1 127.0.0.1:50000", "/ep: topic /joint_states"]
    endpoint, one, joint_states = statuses
    assert values(endpoint)["address"] == "127.0.0.1:10000" and endpoint.level == OK
    assert values(one)["address"] == "127.0.0.1:50000" and values(one)["connected for [s]"] == "10.0"
    assert (
        values(one)["last ping clock offset to ROS [s]"] == "0.250000"
        and values(one)["last ping round trip [s]"] == "-"
    )
    assert one.level == OK and values(joint_states)["subscribed clients"] == "2"
    assert values(joint_states)["ROS publishers"] == "1" and values(joint_states)["ROS subscribers"] == "3"
    # rates between two reports
    later = TopicSnapshot(
        "/joint_states",
        "sensor_msgs/JointState",
        2,
        1,
        to_clients=1500,
        from_clients=150,
        ros_publishers=1,
        ros_subscribers=3,
    )
    statuses, _ = report("/ep", "127.0.0.1:10000", 1012.0, [client()], [later], counts, 2.0)
    assert values(statuses[2])["rate to clients [msg/s]"] == "500.0"
    assert values(statuses[2])["rate from clients [msg/s]"] == "25.0"


def test_refused_web_pages_are_counted_where_websocket_clients_are_served() -> None:
    def endpoint_values(refused: int | None) -> dict[str, str]:
        statuses, _ = report("/ep", "a", 0.0, [], [], {}, 1.0, refused)
        return dict(statuses[0].values)

    assert endpoint_values(3)["WebSocket upgrades refused for their origin"] == "3"
    assert "WebSocket upgrades refused for their origin" not in endpoint_values(None)


def test_a_client_that_drops_or_fills_its_queue_is_a_warning() -> None:
    _, counts = report("/ep", "a", 0.0, [client()], [], {}, 1.0)
    statuses, counts = report("/ep", "a", 1.0, [client(dropped_out=7)], [], counts, 1.0)
    assert statuses[1].level == WARN and "7" in statuses[1].message
    statuses, _ = report("/ep", "a", 2.0, [client(dropped_out=7)], [], counts, 1.0)
    assert statuses[1].level == OK  # no new drops
    statuses, _ = report("/ep", "a", 3.0, [client(queued_frames=600, oldest_queued_age_s=0.8)], [], {}, 1.0)
    assert statuses[1].level == WARN and values(statuses[1])["oldest queued frame age [s]"] == "0.800"


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("2026-11-23T04:00:00.1234567Z", datetime(2026, 11, 23, 4, 0, 0, tzinfo=timezone.utc).timestamp() + 0.1234567),
        ("2026-11-23T05:00:00+01:00", datetime(2026, 11, 23, 4, 0, 0, tzinfo=timezone.utc).timestamp()),
        ("2026-11-23T04:00:00", datetime(2026, 11, 23, 4, 0, 0, tzinfo=timezone.utc).timestamp()),
    ],
)
def test_client_times_in_unitys_round_trip_format_and_others(text: str, expected: float) -> None:
    assert parse_client_time(text) == pytest.approx(expected, abs=1e-6)


@pytest.mark.parametrize("text", ["", "yesterday", "2026-13-40T00:00:00Z", "12:00"])
def test_anything_else_is_no_time(text: str) -> None:
    assert parse_client_time(text) is None
