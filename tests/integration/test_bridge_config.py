"""Endpoint settings and lifecycle: auth token, allow/deny lists, default loopback bind, bad settings refused by name,
clean SIGTERM, and the catkin package's roslaunch entry point."""

from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path

import pytest
from std_msgs.msg import String

from measuring.procfs import listening_addresses
from tests.integration.bridge_helpers import (
    Inbox,
    RawConnection,
    RosInbox,
    serialize,
    service_exists,
    start_endpoint,
    tcp_client,
    unique,
    wait_subscribers,
)
from tests.rosenv import PYTHON, REPO, ManagedProcess, free_port, wait_for

pytestmark = pytest.mark.lane("endpoint", on=("noetic",))

TOKEN = "s3cret-token"


@pytest.fixture(scope="module")
def auth_endpoint(roscore, ros_node, tmp_path_factory):
    process = start_endpoint(roscore, tmp_path_factory.mktemp("auth"), "--auth-token", TOKEN)
    yield process
    process.stop()


@pytest.fixture(scope="module")
def authenticated_observer(auth_endpoint):
    client = tcp_client(auth_endpoint.port, reconnect=False, auth_token=TOKEN)
    yield client
    client.close()


@pytest.mark.parametrize(
    ("first_command", "payload", "fragments"),
    [
        ("__subscribe", b'{"topic":"/t","message_name":"std_msgs/String"}', ["authentication required"]),
        ("__topic_list", b"{}", ["authentication required"]),
        ("__auth", b'{"token":"wrong"}', ["authentication required"]),
        ("__auth", b'{"token":""}', ["authentication required"]),
        ("__auth", b'{"token":12345}', ["__auth", "'token'"]),
        ("__auth", b'{"user":"x"}', ["__auth", "missing field 'token'"]),
    ],
)
def test_missing_or_wrong_token_gets_an_error_and_the_connection_closes(
    auth_endpoint, authenticated_observer, first_command: str, payload: bytes, fragments: list[str]
) -> None:
    from bridge import protocol

    with RawConnection(auth_endpoint.port) as client:
        client.send(protocol.KEEPALIVE_FRAME)  # like Unity: a keepalive first, which needs no token
        client.send(protocol.encode_frame(first_command, payload))
        client.expect_error(*fragments)
        client.wait_closed(timeout=5)
        assert not any(frame.destination == "__topic_list" for frame in client.received)
    authenticated_observer.topic_list()  # the authenticated client never noticed
    assert authenticated_observer.connections == 1 and authenticated_observer.errors == []


def test_right_token_works(auth_endpoint, ros_node) -> None:
    topic = unique("authed")
    publisher = ros_node.Publisher(topic, String, queue_size=10)
    with RawConnection(auth_endpoint.port) as client:
        client.command("__auth", token=TOKEN)
        client.subscribe(topic, "std_msgs/String")
        client.command("__auth", token=TOKEN, user="x")  # a second __auth is harmless; unknown fields are ignored
        client.sync()
        wait_subscribers(publisher)
        publisher.publish(String("for authenticated eyes"))
        frame = client.wait_frame(lambda f: f.destination == topic, f"message on {topic}")
        assert frame.payload == serialize(String("for authenticated eyes"))
        assert client.errors() == []
    publisher.unregister()


def test_tcp_client_with_token_reconnects_and_authenticates_again(auth_endpoint) -> None:
    with tcp_client(auth_endpoint.port, auth_token=TOKEN) as client:
        client.topic_list()
        client.send_raw(b"\xff\xff\xff\xff")  # cut: the endpoint closes, the client reconnects with its token
        wait_for(lambda: client.connections == 2 and client.is_connected, 10, "reconnect")
        client.topic_list()
        assert all("authentication" not in text for text in client.errors)


def test_deny_list(roscore, ros_node, tmp_path: Path) -> None:
    endpoint = start_endpoint(roscore, tmp_path, "--deny", "/secret*")
    try:
        with RawConnection(endpoint.port) as client:
            client.subscribe("/secret_plans", "std_msgs/String")
            assert "/secret_plans" in client.expect_error("not permitted")
            client.subscribe("secret_relative", "std_msgs/String")  # resolved before matching
            assert "/secret_relative" in client.expect_error("not permitted")
            client.register_publisher("/secret/cmd", "std_msgs/String")
            assert "/secret/cmd" in client.expect_error("not permitted")
            client.command("__ros_service", topic="/secret_srv", message_name="std_srvs/Trigger")
            assert "/secret_srv" in client.expect_error("not permitted")
            client.command("__unity_service", topic="/secret_offer", message_name="std_srvs/Trigger")
            assert "/secret_offer" in client.expect_error("not permitted")
            open_topic = unique("public")
            client.subscribe(open_topic, "std_msgs/String")
            client.register_publisher(open_topic + "_out", "std_msgs/String")
            client.sync()
            assert len(client.errors()) == 5
        assert not service_exists(ros_node, "/secret_offer")
    finally:
        endpoint.stop()


def test_allow_list_with_deny_exception(roscore, ros_node, tmp_path: Path) -> None:
    endpoint = start_endpoint(roscore, tmp_path, "--allow", "/open/*", "--deny", "/open/secret*")
    try:
        with RawConnection(endpoint.port) as client:
            client.subscribe("/open/chatter", "std_msgs/String")
            client.sync()
            assert client.errors() == []
            client.subscribe("/closed", "std_msgs/String")
            client.expect_error("/closed", "not permitted")
            client.subscribe("/open/secret_x", "std_msgs/String")
            client.expect_error("/open/secret_x", "not permitted")
            client.sync()
    finally:
        endpoint.stop()


def test_default_bind_is_loopback(endpoint) -> None:
    assert f"listening on 127.0.0.1:{endpoint.port}" in endpoint.output()
    assert listening_addresses(endpoint.port) == {"0100007F"}  # 127.0.0.1, little-endian hex


def test_sigterm_stops_the_endpoint_cleanly(roscore, ros_node, tmp_path: Path) -> None:
    endpoint = start_endpoint(roscore, tmp_path)
    service = unique("sigterm_srv")
    try:
        client = tcp_client(endpoint.port, reconnect=False)
        client.subscribe(unique("sigterm_topic"), "std_msgs/String", Inbox())
        client.implement_service(service, "std_srvs/Trigger", lambda _: b"")
        client.topic_list()
        wait_for(lambda: service_exists(ros_node, service), 10, f"{service} advertised")
        os.kill(endpoint.process.pid, signal.SIGTERM)
        assert endpoint.process.wait(timeout=15) == 0, endpoint.output()[-3000:]
        wait_for(lambda: not client.is_connected, 10, "the client to see the connection closed")
        assert "endpoint stopped" in endpoint.output()
        assert not service_exists(ros_node, service)
        client.close()
    finally:
        endpoint.stop()


@pytest.mark.parametrize(
    ("options", "param", "named"),
    [
        (["--queue-frames", "0"], None, "--queue-frames / ~queue_frames: must be a whole number of at least 1, got 0"),
        (["--tcp-port", "70000"], None, "--tcp-port / ~tcp_port (/ROS_TCP_PORT): must be a whole number from 0"),
        (["--service-timeout", "-1"], None, "--service-timeout / ~service_timeout: must be a positive number"),
        ([], ("tcp_port", "abc"), "--tcp-port / ~tcp_port (/ROS_TCP_PORT): 'abc' is not a whole number"),
        ([], ("validate_payloads", "maybe"), "--no-validate / ~validate_payloads: 'maybe' is not true or false"),
    ],
)
def test_a_bad_setting_stops_the_endpoint_at_once_with_a_message_naming_it(
    roscore, ros_node, options: list[str], param: tuple[str, str] | None, named: str
) -> None:
    node = unique("bad_setting").lstrip("/")
    if param is not None:
        ros_node.set_param(f"/{node}/{param[0]}", param[1])
    try:
        result = subprocess.run(
            [PYTHON, "-m", "bridge", "--node-name", node, *options],
            env=roscore.env,
            cwd=REPO,
            capture_output=True,
            text=True,
            timeout=60,
        )
    finally:
        if param is not None:
            ros_node.delete_param(f"/{node}/{param[0]}")
    assert result.returncode == 2, result.stderr
    assert f"python -m bridge: bad setting {named}" in result.stderr
    assert "Traceback" not in result.stderr and "listening" not in result.stdout


def test_roslaunch_endpoint_launch_serves_clients_like_unitys(roscore, ros_node, tmp_path: Path) -> None:
    """The catkin package's launch file, as a Unity user starts it, with its two arguments."""
    port = free_port()
    command = (
        f"source {REPO}/catkin_ws/devel/setup.bash && exec roslaunch ros_tcp_endpoint endpoint.launch "
        f"tcp_ip:=127.0.0.1 tcp_port:={port}"
    )
    launch = ManagedProcess(["bash", "-c", command], roscore.env, tmp_path, "roslaunch")
    to_ros, to_client = unique("launched_in"), unique("launched_out")
    inbox = RosInbox(ros_node, to_ros)
    publisher = ros_node.Publisher(to_client, String, queue_size=10)
    try:
        launch.wait_for_output(f"listening on 127.0.0.1:{port}", timeout=60)
        assert ros_node.get_param("/ros_tcp_endpoint/actual_port") == port
        received = Inbox()
        with tcp_client(port, reconnect=False) as client:
            client.subscribe(to_client, "std_msgs/String", received)
            client.register_publisher(to_ros, "std_msgs/String")
            client.topic_list()  # answered after the registrations before it
            inbox.wait_connected()
            client.publish(to_ros, serialize(String("to ROS")))
            assert inbox.wait_count(1) == [serialize(String("to ROS"))]
            wait_subscribers(publisher)
            publisher.publish(String("to the client"))
            assert received.wait_count(1) == [serialize(String("to the client"))]
            assert client.errors == []
        launch.stop(timeout=15)
        assert "endpoint stopped" in launch.output()
    finally:
        launch.stop()
        inbox.close()
        publisher.unregister()
        for name in ("tcp_ip", "tcp_port", "auth_token", "actual_port"):
            if ros_node.has_param(f"/ros_tcp_endpoint/{name}"):
                ros_node.delete_param(f"/ros_tcp_endpoint/{name}")
