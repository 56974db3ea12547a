"""What the endpoint reports on /diagnostics, as plain data: one status for the endpoint, one per client, one per
bridged topic (bridge.ros.graph publishes them as diagnostic_msgs/DiagnosticArray, which rqt_runtime_monitor and
`rostopic echo /diagnostics` show; bridge.ros.peer_links adds one per link to a ROS peer that does not come up). Pure:
snapshots in, statuses out; imports neither socket nor rospy.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Sequence

__all__ = ["OK", "WARN", "ClientSnapshot", "TopicSnapshot", "Status", "report", "parse_client_time"]

# diagnostic_msgs/DiagnosticStatus levels
OK, WARN = 0, 1


@dataclass(frozen=True)
class ClientSnapshot:
    name: str  # "#3 127.0.0.1:50312"
    connected_at: float  # wall clock, s since the epoch
    authenticated: bool
    frames_in: int
    frames_out: int
    bytes_in: int
    bytes_out: int
    queued_frames: int
    queue_capacity: int
    oldest_queued_age_s: float | None
    dropped_out: int  # frames for the client dropped because it read too slowly
    dropped_in: int  # the client's messages dropped because ROS subscribers took them too slowly
    pings: int
    # ROS time when the endpoint answered the client's last ping, minus the client's clock when it sent it: the
    # client's clock offset to ROS time plus the one-way delay (None before a ping with a readable time)
    ping_clock_offset_s: float | None
    ping_round_trip_s: float | None  # as the client measured it, if it says (TcpClient.ping does not yet)


@dataclass(frozen=True)
class TopicSnapshot:
    topic: str
    message_name: str
    subscribed_clients: int  # clients receiving it from ROS
    publishing_clients: int  # clients publishing it to ROS
    to_clients: int  # messages from ROS fanned out so far
    from_clients: int  # client messages handed to the ROS publisher so far
    ros_publishers: int  # connections from ROS publishers to the endpoint's subscriber
    ros_subscribers: int  # connections from ROS subscribers to the endpoint's publisher
    # The longest one of its messages waited in a client's queue before being written, since the last report (None:
    # none was queued; messages written at once do not wait): the endpoint's share of their age at the client.
    longest_wait_s: float | None = None


@dataclass(frozen=True)
class Status:
    """One diagnostic_msgs/DiagnosticStatus."""

    level: int
    name: str
    message: str
    hardware_id: str
    values: tuple[tuple[str, str], ...]


def report(
    node: str,
    address: str,
    now: float,
    clients: Sequence[ClientSnapshot],
    topics: Sequence[TopicSnapshot],
    previous: dict[str, tuple[int, int]],
    interval_s: float,
    refused_origins: int | None = None,
) -> tuple[list[Status], dict[str, tuple[int, int]]]:
    """The statuses at wall time `now`, and the counts to pass as `previous` next time (rates and new drops are
    measured between two reports `interval_s` apart). `refused_origins`: WebSocket upgrades refused for their
    Origin so far (None: the endpoint serves no WebSocket clients)."""
    counts: dict[str, tuple[int, int]] = {}
    websocket = (
        () if refused_origins is None else (("WebSocket upgrades refused for their origin", str(refused_origins)),)
    )
    statuses = [
        Status(
            OK,
            f"{node}: endpoint",
            f"{len(clients)} client(s), {len(topics)} topic(s)",
            node,
            (
                ("address", address),
                ("clients", str(len(clients))),
                ("topics", str(len(topics))),
                *websocket,
            ),
        )
    ]
    for client in clients:
        key = f"client {client.name}"
        counts[key] = (client.dropped_out, client.dropped_in)
        before = previous.get(key, (client.dropped_out, client.dropped_in))
        new_drops = (client.dropped_out - before[0]) + (client.dropped_in - before[1])
        backlog = client.queued_frames >= client.queue_capacity // 2
        level = WARN if new_drops or backlog else OK
        message = (
            f"dropping messages ({new_drops} in the last {interval_s:g} s)"
            if new_drops
            else "reading too slowly: its queue is half full"
            if backlog
            else "ok"
        )
        statuses.append(
            Status(
                level,
                f"{node}: {key}",
                message,
                node,
                (
                    ("address", client.name.split(" ", 1)[-1]),
                    ("connected since", _iso(client.connected_at)),
                    ("connected for [s]", f"{now - client.connected_at:.1f}"),
                    ("authenticated", "yes" if client.authenticated else "no"),
                    ("frames in", str(client.frames_in)),
                    ("frames out", str(client.frames_out)),
                    ("bytes in", str(client.bytes_in)),
                    ("bytes out", str(client.bytes_out)),
                    ("queued frames", f"{client.queued_frames}/{client.queue_capacity}"),
                    ("oldest queued frame age [s]", _maybe(client.oldest_queued_age_s, "{:.3f}")),
                    ("dropped to client", str(client.dropped_out)),
                    ("dropped from client", str(client.dropped_in)),
                    ("pings", str(client.pings)),
                    ("last ping round trip [s]", _maybe(client.ping_round_trip_s, "{:.6f}")),
                    ("last ping clock offset to ROS [s]", _maybe(client.ping_clock_offset_s, "{:.6f}")),
                ),
            )
        )
    for topic in topics:
        key = f"topic {topic.topic}"
        counts[key] = (topic.to_clients, topic.from_clients)
        before = previous.get(key, (topic.to_clients, topic.from_clients))
        rate_to = (topic.to_clients - before[0]) / interval_s
        rate_from = (topic.from_clients - before[1]) / interval_s
        statuses.append(
            Status(
                OK,
                f"{node}: {key}",
                f"{rate_to:.1f} msg/s to clients, {rate_from:.1f} msg/s from clients",
                node,
                (
                    ("type", topic.message_name),
                    ("subscribed clients", str(topic.subscribed_clients)),
                    ("publishing clients", str(topic.publishing_clients)),
                    ("ROS publishers", str(topic.ros_publishers)),
                    ("ROS subscribers", str(topic.ros_subscribers)),
                    ("rate to clients [msg/s]", f"{rate_to:.1f}"),
                    ("rate from clients [msg/s]", f"{rate_from:.1f}"),
                    ("messages to clients", str(topic.to_clients)),
                    ("messages from clients", str(topic.from_clients)),
                    ("longest wait in a client queue [s]", _maybe(topic.longest_wait_s, "{:.3f}")),
                ),
            )
        )
    return statuses, counts


_CLIENT_TIME = re.compile(r"(\d{4})-(\d{2})-(\d{2})T(\d{2}):(\d{2}):(\d{2})(?:\.(\d+))?(Z|[+-]\d{2}:?\d{2})?$")


def parse_client_time(text: str) -> float | None:
    """Seconds since the epoch of an ISO-8601 time as clients send it in __ping (Unity writes DateTime's round-trip
    format, e.g. 2026-11-23T04:00:00.1234567Z: seven fractional digits, which Python 3.8's fromisoformat refuses);
    a time without a zone is taken as UTC. None when it is not such a time."""
    match = _CLIENT_TIME.match(text.strip())
    if match is None:
        return None
    year, month, day, hour, minute, second = (int(part) for part in match.groups()[:6])
    fraction, zone = match.group(7) or "0", match.group(8) or "Z"
    try:
        moment = datetime(year, month, day, hour, minute, second, tzinfo=timezone.utc).timestamp()
    except ValueError:
        return None
    if zone != "Z":
        sign = -1 if zone[0] == "-" else 1
        digits = zone[1:].replace(":", "")
        moment -= sign * (int(digits[:2]) * 3600 + int(digits[2:]) * 60)
    return moment + float(f"0.{fraction}")


def _iso(seconds: float) -> str:
    return datetime.fromtimestamp(seconds, timezone.utc).isoformat(timespec="seconds")


def _maybe(value: float | None, spec: str) -> str:
    return "-" if value is None else spec.format(value)
