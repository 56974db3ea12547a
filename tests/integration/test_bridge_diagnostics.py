"""A window into the endpoint: /diagnostics (diagnostic_msgs/DiagnosticArray, 1 Hz) and its log lines."""

from __future__ import annotations

import pytest
from std_msgs.msg import String

from tests.integration.bridge_helpers import (
    DiagnosticsInbox,
    RawConnection,
    RosInbox,
    serialize,
    start_endpoint,
    status_values,
    tcp_client,
    unique,
    wait_subscribers,
)
from tests.rosenv import wait_for

pytestmark = pytest.mark.lane("endpoint", on=("noetic",))


def test_diagnostics_show_each_client_and_topic(roscore, ros_node, tmp_path) -> None:
    endpoint = start_endpoint(roscore, tmp_path)
    node = "/" + endpoint.name
    topic_out, topic_in = unique("diag_out"), unique("diag_in")
    publisher = ros_node.Publisher(topic_out, String, queue_size=100)
    inbox = RosInbox(ros_node, topic_in)
    diagnostics = DiagnosticsInbox(ros_node, node)
    try:
        with tcp_client(endpoint.port) as client:
            client.subscribe(topic_out, "std_msgs/String", lambda payload: None)
            client.register_publisher(topic_in, "std_msgs/String")
            client.topic_list()
            wait_subscribers(publisher)
            inbox.wait_connected()
            client.ping()
            client.ping()  # tells the endpoint the first one's round trip
            for index in range(50):
                publisher.publish(String(f"out {index}"))
                client.publish(topic_in, serialize(String(f"in {index}")))
            inbox.wait_count(50)
            wait_for(
                lambda: (s := diagnostics.find(topic_out)) and status_values(s)["messages to clients"] == "50",
                10,
                "the topic's count on /diagnostics",
            )
            mine = diagnostics.find("client #")
            assert mine is not None and mine.level == 0
            shown = status_values(mine)
            assert shown["address"].startswith("127.0.0.1:") and shown["authenticated"] == "yes"
            assert shown["pings"] == "2" and float(shown["last ping round trip [s]"]) > 0
            assert abs(float(shown["last ping clock offset to ROS [s]"])) < 1.0
            assert int(shown["frames in"]) >= 55 and int(shown["bytes out"]) > 0
            assert status_values(diagnostics.find(topic_in))["messages from clients"] == "50"
            assert status_values(diagnostics.find(topic_in))["publishing clients"] == "1"
            assert status_values(diagnostics.find(topic_in))["ROS subscribers"] == "1"  # the test's RosInbox
            assert status_values(diagnostics.find(topic_out))["ROS publishers"] == "1"  # the test's publisher
            assert status_values(diagnostics.find("endpoint"))["clients"] == "1"
        wait_for(lambda: "disconnected: closed by the client" in endpoint.output(), 10, "the disconnect's log line")
        wait_for(lambda: diagnostics.find("client #") is None, 10, "the client gone from /diagnostics")
    finally:
        diagnostics.close()
        inbox.close()
        publisher.unregister()
        endpoint.stop()


def test_every_accept_auth_failure_and_disconnect_is_logged_with_its_reason(roscore, ros_node, tmp_path) -> None:
    endpoint = start_endpoint(roscore, tmp_path, "--auth-token", "s3cret")
    try:
        with RawConnection(endpoint.port) as wrong:
            wrong.command("__auth", token="guess")
            wrong.wait_closed(timeout=10)
        wait_for(
            lambda: "disconnected: authentication failed (a wrong token" in endpoint.output(),
            10,
            "the disconnect's line, with its reason",
        )
        output = endpoint.output()
        assert "connected; handshake sent, waiting for __auth" in output
        assert "client #1 127.0.0.1" in output and "authentication failed (a wrong token, 1 in a row" in output
    finally:
        endpoint.stop()
