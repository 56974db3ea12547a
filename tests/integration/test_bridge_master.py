"""The ROS master fails under the endpoint: killed and started again on its port, frozen, down for a while.

Each test runs its own roscore (the session's is never touched) and an endpoint on it.
"""

from __future__ import annotations

import os
import signal
import socket
import struct
import time
import xmlrpc.client
from collections.abc import Iterator
from pathlib import Path

import pytest
from std_msgs.msg import String

from bridge import protocol
from bridge.client import ClientError, TcpClient
from tests.integration.bridge_helpers import Inbox, RawConnection, serialize, start_endpoint, tcp_client, unique
from tests.rosenv import EndpointProcess, ManagedProcess, RosCore, wait_for

pytestmark = pytest.mark.lane("endpoint", on=("noetic",))


def trigger_response(message: str) -> bytes:
    """std_srvs/Trigger's response, serialized: success, message."""
    return b"\x01" + struct.pack("<I", len(message)) + message.encode()


class Graph:
    """What a master holds: {name: nodes} for publishers, subscribers and services."""

    def __init__(self, core: RosCore) -> None:
        state = xmlrpc.client.ServerProxy(core.uri).getSystemState("/probe")[2]
        self.publishers, self.subscribers, self.services = (
            {name: set(nodes) for name, nodes in part} for part in state
        )


def holds(core: RosCore, node: str, publishers=(), subscribers=(), services=()) -> bool:
    try:
        graph = Graph(core)
    except OSError:
        return False
    return (
        all(node in graph.publishers.get(name, ()) for name in publishers)
        and all(node in graph.subscribers.get(name, ()) for name in subscribers)
        and all(node in graph.services.get(name, ()) for name in services)
    )


@pytest.fixture
def core(tmp_path: Path) -> Iterator[RosCore]:
    started = RosCore(tmp=tmp_path / "core")
    yield started
    started.stop()


@pytest.fixture
def endpoint(core: RosCore, tmp_path: Path) -> Iterator[EndpointProcess]:
    process = start_endpoint(core, tmp_path, "--service-timeout", "3", name="master_test_endpoint")
    yield process
    process.stop()


def restart(core: RosCore) -> RosCore:
    """Kill the roscore (its whole process group) and start another on the same port."""
    core.stop()
    return RosCore(port=core.port, tmp=core.tmp)


def ros_tool(core: RosCore, tmp_path: Path, *args: str) -> ManagedProcess:
    return ManagedProcess(list(args), core.env, tmp_path, Path(args[0]).name)


def test_a_restarted_master_gets_every_registration_back_without_the_client_doing_anything(
    core: RosCore, endpoint: EndpointProcess, tmp_path: Path
) -> None:
    node = "/master_test_endpoint"
    published, subscribed, service, late = unique("m_pub"), unique("m_sub"), unique("m_srv"), unique("m_late")
    inbox = Inbox()
    client = tcp_client(endpoint.port, reconnect=False)
    try:
        client.register_publisher(published, "std_msgs/String")
        client.subscribe(subscribed, "std_msgs/String", inbox)
        client.implement_service(service, "std_srvs/Trigger", lambda request: trigger_response("from the client"))
        client.topic_list()
        wait_for(lambda: holds(core, node, [published], [subscribed], [service]), 10, "registrations")

        core.stop()
        # While the master is down: clients are still accepted and served, and may register more.
        client.subscribe(late, "std_msgs/String", inbox)
        client.ping()
        newcomer = tcp_client(endpoint.port, reconnect=False)
        newcomer.ping()
        newcomer.close()

        core = restart(core)
        started = time.monotonic()
        wait_for(
            lambda: holds(core, node, [published], [subscribed, late], [service]),
            15,
            "every registration on the new master",
        )
        print(f"registered again {time.monotonic() - started:.2f} s after the new master was up")

        # ROS nodes started now reach the client's topics and service, both ways.
        echo = ros_tool(core, tmp_path, "rostopic", "echo", "-n", "1", published)
        sent = 0
        while 'data: "hello' not in echo.output() and sent < 100:
            client.publish(published, serialize(String(f"hello {sent}")))
            sent += 1
            time.sleep(0.1)
        assert 'data: "hello' in echo.output(), echo.output()
        ros_tool(core, tmp_path, "rostopic", "pub", "-1", subscribed, "std_msgs/String", "data: from ROS").wait(30)
        inbox.wait_count(1)
        assert inbox.snapshot()[0] == serialize(String("from ROS"))
        answer = ros_tool(core, tmp_path, "rosservice", "call", service)
        answer.wait(30)
        assert "from the client" in answer.output(), answer.output()
        assert client.is_connected and client.connections == 1 and client.errors == []
    finally:
        client.close()
        core.stop()


def master_pid(core: RosCore) -> int:
    return int(xmlrpc.client.ServerProxy(core.uri).getPid("/probe")[2])


def test_a_frozen_master_holds_up_no_client_and_gets_the_registrations_when_it_thaws(
    core: RosCore, endpoint: EndpointProcess
) -> None:
    node = "/master_test_endpoint"
    topic, published = unique("f_sub"), unique("f_pub")
    client = tcp_client(endpoint.port, reconnect=False)
    pid = master_pid(core)
    os.kill(pid, signal.SIGSTOP)
    try:
        client.subscribe(topic, "std_msgs/String", Inbox())  # used to wait for the master under the endpoint's lock
        client.register_publisher(published, "std_msgs/String")
        client.ping()
        newcomer: TcpClient = tcp_client(endpoint.port, reconnect=False)  # accepted, handshake and all
        newcomer.ping()
        newcomer.close()
        with pytest.raises(ClientError):  # what needs the master says so, in time
            client.topic_list(timeout=8)
        assert any("did not answer" in error for error in client.errors), client.errors
    finally:
        os.kill(pid, signal.SIGCONT)
    try:
        wait_for(lambda: holds(core, node, [published], [topic]), 15, "registrations once the master thaws")
        client.topic_list()
        assert client.is_connected and client.connections == 1
    finally:
        client.close()


def test_sigterm_ends_the_endpoint_within_seconds_whatever_is_in_flight(core: RosCore, tmp_path: Path) -> None:
    """A hung ROS service call, a ROS caller waiting for a client, a client that reads nothing, a frozen master."""
    endpoint = start_endpoint(core, tmp_path, "--service-timeout", "60", name="sigterm_endpoint")
    hung_service, client_service = unique("never_answers"), unique("client_never_answers")
    silent_server = socket.create_server(("127.0.0.1", 0))  # a ROS service that accepts and never answers
    master = xmlrpc.client.ServerProxy(core.uri)
    master.registerService(
        "/fake_node", hung_service, f"rosrpc://127.0.0.1:{silent_server.getsockname()[1]}", "http://127.0.0.1:9/"
    )
    caller = None
    pid = None
    try:
        with RawConnection(endpoint.port) as calling, RawConnection(endpoint.port) as serving, RawConnection(
            endpoint.port, rcvbuf=4096
        ) as silent:
            calling.command("__ros_service", topic=hung_service, message_name="std_srvs/Trigger")
            calling.command("__request", srv_id=1)
            calling.send_frame(hung_service, b"")
            serving.command("__unity_service", topic=client_service, message_name="std_srvs/Trigger")
            serving.sync()
            caller = ros_tool(core, tmp_path, "rosservice", "call", client_service)
            serving.wait_command("__request", timeout=30)  # the ROS caller waits for the client now
            silent.send(protocol.encode_syscommand("__topic_list", {}) * 200)  # answers it never reads
            pid = master_pid(core)
            os.kill(pid, signal.SIGSTOP)
            started = time.monotonic()
            endpoint.process.send_signal(signal.SIGTERM)
            assert endpoint.process.wait(15) == 0
            took = time.monotonic() - started
            print(f"endpoint exited {took:.2f} s after SIGTERM")
            assert took < 8
            serving.wait_frame(
                lambda f: f.destination == "__warn" and b"shutting down" in f.payload,
                "the endpoint saying it shuts down",
            )
            calling.wait_closed()
            # The ROS caller got an error at once, not a hang (it cannot exit before the master thaws: rospy)
            wait_for(lambda: "the endpoint is shutting down" in caller.output(), 10, "the ROS caller's error")
    finally:
        if pid is not None:
            os.kill(pid, signal.SIGCONT)
        if caller is not None:
            caller.stop()
        silent_server.close()
        endpoint.stop()
