"""The endpoint's WebSocket transport (--websocket-port) through a real endpoint: the whole conversation, bad input
at both levels (WebSocket and ROS-TCP), and TCP and WebSocket clients side by side."""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import threading
from collections.abc import Iterator

import pytest
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from std_srvs.srv import SetBool, SetBoolRequest, SetBoolResponse, Trigger, TriggerResponse

from bridge import protocol
from measuring.procfs import rss_bytes
from sim.processes import PYTHON, REPO, ManagedProcess
from tests.integration.bridge_helpers import (
    DiagnosticsInbox,
    Inbox,
    RawConnection,
    RawWebSocket,
    RosInbox,
    fully_connected,
    serialize,
    service_exists,
    start_endpoint,
    status_values,
    tcp_client,
    unique,
)
from tests.rosenv import EndpointProcess, RosCore, wait_for

pytestmark = pytest.mark.lane("endpoint", on=("noetic",))


@pytest.fixture(scope="module")
def bridge(roscore: RosCore, ros_node, tmp_path_factory) -> Iterator[EndpointProcess]:
    process = start_endpoint(
        roscore, tmp_path_factory.mktemp("bridge"), "--websocket-port", "0", "--service-timeout", "2"
    )
    try:
        yield process
    finally:
        process.stop()


def ws_client(endpoint: EndpointProcess, **kwargs):
    assert endpoint.websocket_port is not None
    return tcp_client(endpoint.websocket_port, websocket=True, **kwargs)


def joint_state(position: float) -> JointState:
    return JointState(name=["a", "b"], position=[position, -position], velocity=[0.0, 0.0], effort=[])


# --- the whole conversation --------------------------------------------------------------------------------------


def test_a_websocket_client_does_the_whole_conversation(bridge, ros_node) -> None:
    to_client, from_client = unique("ws_down"), unique("ws_up")
    set_bool, trigger = unique("ws_set_bool"), unique("ws_trigger")
    publisher = ros_node.Publisher(to_client, JointState, queue_size=10)
    from_ros = RosInbox(ros_node, from_client)
    service = ros_node.Service(set_bool, SetBool, lambda request: SetBoolResponse(not request.data, "ros answered"))
    received = Inbox()
    with ws_client(bridge, reconnect=False) as client:
        assert client.handshake is not None and client.handshake.is_compatible
        # subscribe: ROS -> client
        client.subscribe(to_client, "sensor_msgs/JointState", received)
        wait_for(lambda: publisher.get_num_connections() == 1, 10, "the endpoint's subscriber")
        for step in range(5):
            publisher.publish(joint_state(step / 10))
        positions = [tuple(JointState().deserialize(payload).position) for payload in received.wait_count(5)]
        assert positions == [(step / 10, -step / 10) for step in range(5)]
        # publish: client -> ROS
        client.register_publisher(from_client, "std_msgs/String")
        from_ros.wait_connected()
        client.publish(from_client, serialize(String(data="from the browser")))
        assert from_ros.wait_count(1) == [serialize(String(data="from the browser"))]
        # a ROS service, called by the client
        client.register_ros_service(set_bool, "std_srvs/SetBool")
        answer = client.call_service(set_bool, serialize(SetBoolRequest(data=True)), timeout=10)
        assert answer == serialize(SetBoolResponse(success=False, message="ros answered"))
        # a service the client offers, called from ROS
        client.implement_service(trigger, "std_srvs/Trigger", lambda request: serialize(TriggerResponse(True, "ws")))
        wait_for(lambda: service_exists(ros_node, trigger), 10, f"{trigger} advertised")
        assert ros_node.ServiceProxy(trigger, Trigger)().message == "ws"
        # __ping: a round trip, and the ROS clock's offset (wall time here, so near zero)
        ping = client.ping()
        assert ping.round_trip_s < 1 and ping.ros_clock_offset_s is not None and abs(ping.ros_clock_offset_s) < 1
        assert client.topic_list()[to_client] == "sensor_msgs/JointState"
        assert client.errors == []
    service.shutdown()
    publisher.unregister()
    from_ros.close()


def test_every_frame_is_one_binary_message(bridge, ros_node) -> None:
    """Topic messages, commands, and a service response's header and body (sent by the endpoint as one item) each
    come as a binary message of their own."""
    topic, name = unique("ws_one_frame"), unique("ws_one_frame_srv")
    publisher = ros_node.Publisher(topic, String, queue_size=10)
    service = ros_node.Service(name, SetBool, lambda request: SetBoolResponse(True, "x" * 70000))
    with RawWebSocket(bridge.websocket_port) as ws:
        assert ws.handshake is not None and ws.handshake["version"] == "v0.7.0"
        ws.command("__subscribe", topic=topic, message_name="std_msgs/String")
        ws.command("__ros_service", topic=name, message_name="std_srvs/SetBool")
        ws.sync()
        wait_for(lambda: publisher.get_num_connections() == 1, 10, "the endpoint's subscriber")
        for text in ("one", "two"):
            publisher.publish(String(data=text))
        ws.wait_frame(lambda frame: frame.payload == serialize(String(data="two")), "the second message")
        ws.command("__request", srv_id=7)
        ws.send_frame(name, serialize(SetBoolRequest(data=True)))
        header = ws.wait_frame(lambda frame: frame.destination == "__response", "__response")
        body = ws.next_frame()
        assert json.loads(header.payload)["srv_id"] == 7
        assert body.destination == name and body.payload == serialize(SetBoolResponse(True, "x" * 70000))
        assert ws.messages == len(ws.received)  # RawWebSocket asserted one frame in each
    service.shutdown()
    publisher.unregister()


def test_tcp_and_websocket_clients_share_a_topic(bridge, ros_node) -> None:
    topic = unique("ws_shared")
    from_ros = RosInbox(ros_node, topic)
    by_tcp, by_ws = Inbox(), Inbox()
    with tcp_client(bridge.port, reconnect=False) as tcp, ws_client(bridge, reconnect=False) as ws:
        for client, inbox in ((tcp, by_tcp), (ws, by_ws)):
            client.subscribe(topic, "std_msgs/String", inbox)
            client.register_publisher(topic, "std_msgs/String")
        publisher = ros_node.Publisher(topic, String, queue_size=10)
        # both publishers (the endpoint's, the test's) to both subscribers (the endpoint's, the test's): the clients
        # get each other's messages through the endpoint's own subscriber to its own publisher
        wait_for(lambda: fully_connected(ros_node, topic), 10, "every publisher of the topic to every subscriber")
        tcp.publish(topic, serialize(String(data="tcp")))
        ws.publish(topic, serialize(String(data="ws")))
        publisher.publish(String(data="ros"))
        everything = {serialize(String(data=text)) for text in ("tcp", "ws", "ros")}
        # both clients' messages reach ROS (whether the test's own subscriber has the test's own "ros" is rospy's
        # affair within this process: beside CPU burners it sometimes had not, its self-connection not yet reading)
        from_clients = {serialize(String(data="tcp")), serialize(String(data="ws"))}
        wait_for(lambda: from_clients <= set(from_ros.snapshot()), 10, "both clients' messages on ROS")
        # each client gets the others' messages and ROS's, not its own back (the endpoint's default)
        assert set(by_tcp.wait_count(2)) == everything - {serialize(String(data="tcp"))}
        assert set(by_ws.wait_count(2)) == everything - {serialize(String(data="ws"))}
        publisher.unregister()
    from_ros.close()


def test_a_slow_websocket_reader_loses_old_messages_and_is_told_in_a_message(bridge, ros_node) -> None:
    """The endpoint's own notices (here the drop warning its writer adds) travel as binary messages too.

    The reader starts only once /diagnostics says the endpoint has fanned out every message and dropped some for it:
    rospy's publish() only queues, so a reader that started when the loop returned read while the messages were
    still arriving, kept up, lost nothing, and rightly got no warning (the test that failed now and then)."""
    topic = unique("ws_slow")
    publisher = ros_node.Publisher(topic, String, queue_size=2000)
    diagnostics = DiagnosticsInbox(ros_node, "/" + bridge.name)
    count = 1200  # 60 MB unread: more than the socket buffers could ever hold (32 + 4 MiB here) and the queue (4 MiB)
    try:
        with RawWebSocket(bridge.websocket_port) as ws:
            ws.command("__subscribe", topic=topic, message_name="std_msgs/String")
            ws.sync()
            wait_for(lambda: publisher.get_num_connections() == 1, 10, "the endpoint's subscriber")
            for index in range(count):
                publisher.publish(String(data=f"{index:06d}" + "x" * 50_000))
            wait_for(lambda: _fanned_out(diagnostics, topic) == count, 60, f"{count} messages fanned out")
            client = f"127.0.0.1:{ws.sock.getsockname()[1]}"
            wait_for(lambda: _dropped_for_client(diagnostics, client) > 0, 10, "drops counted for the client")
            # The newest message and a warning that counts the drops, in either order (the warning goes with the
            # batch after the drops it counts; a batch taken while drops were still happening may carry an early one)
            newest = f"{count - 1:06d}".encode()
            ws.wait_frame(lambda frame: frame.destination == topic and frame.payload[4:10] == newest, "the newest")
            warnings = [frame for frame in ws.received if _is_drop_warning(frame)]
            warning = warnings[0] if warnings else ws.wait_frame(_is_drop_warning, "a drop warning")
            assert b"dropped" in warning.payload and ws.messages == len(ws.received)
            assert len([frame for frame in ws.received if frame.destination == topic]) < count  # the old ones went
    finally:
        diagnostics.close()
        publisher.unregister()


def test_a_websocket_reader_that_keeps_up_loses_nothing_and_is_not_warned(bridge, ros_node) -> None:
    """The other side of the race above, made certain: the reader takes each message before the next is published,
    so the endpoint never has more than one waiting, drops nothing, and has nothing to warn of."""
    topic = unique("ws_keeps_up")
    publisher = ros_node.Publisher(topic, String, queue_size=10)
    with RawWebSocket(bridge.websocket_port) as ws:
        ws.command("__subscribe", topic=topic, message_name="std_msgs/String")
        ws.sync()
        wait_for(lambda: publisher.get_num_connections() == 1, 10, "the endpoint's subscriber")
        for index in range(200):
            publisher.publish(String(data=f"{index:06d}" + "x" * 50_000))
            frame = ws.wait_frame(lambda frame: frame.destination == topic, f"message {index}")
            assert frame.payload[4:10] == f"{index:06d}".encode()
        ws.sync()  # a round trip after the last message: a warning due by then would be on its way
        assert not [frame for frame in ws.received if frame.destination == "__warn"], ws.summary()
    publisher.unregister()


def _is_drop_warning(frame) -> bool:
    return frame.destination == "__warn" and b"reads too slowly" in frame.payload


def _fanned_out(diagnostics: DiagnosticsInbox, topic: str) -> int:
    status = diagnostics.find(f"topic {topic}")
    return -1 if status is None else int(status_values(status)["messages to clients"])


def _dropped_for_client(diagnostics: DiagnosticsInbox, address: str) -> int:
    status = diagnostics.find(address)
    return -1 if status is None else int(status_values(status)["dropped to client"])


# --- answers are bounded ------------------------------------------------------------------------------------------


def test_a_flood_of_pings_gets_one_pong_per_read_and_does_not_grow_the_endpoint(bridge) -> None:
    """200,000 WebSocket pings (26 MB) from a client that reads nothing meanwhile: the endpoint answers only the
    newest of each read (RFC 6455 allows it). Answering each would have queued 200,000 pongs (25 MB and more)."""
    from wsproto.events import Ping

    with RawWebSocket(bridge.websocket_port) as ws:
        ws.sync()
        before = rss_bytes(bridge.pid)
        pings = b"".join(ws.ws.send(Ping(b"%0125d" % n)) for n in range(1000))
        for _ in range(200):
            ws.send_bytes(pings)
        ws.sync()  # everything before it has been read and answered
        assert 1 <= ws.pongs < 20_000, ws.pongs
        assert rss_bytes(bridge.pid) - before < 8 * 1024 * 1024
        pong_before = ws.pongs
        ws.send_event(Ping(b"still answered"))
        ws.sync()
        assert ws.pongs == pong_before + 1


def test_past_the_unread_answers_budget_pongs_are_dropped_and_the_client_is_told(bridge, ros_node) -> None:
    """A client that asks for 24 MB of service answers and reads none has more than its 4 MiB of unread answers
    queued: its pings then get no pong (the budget every answer shares), and a warning says so."""
    from wsproto.events import Ping

    name = unique("ws_big_answers")
    answered = []
    all_asked = threading.Event()

    def big(request):
        # No answer before all 24 are asked: the endpoint refuses a request once 4 MiB of answers wait unread, and
        # calls run at once, so early answers could otherwise get there before the last requests are read.
        answered.append(request)
        if len(answered) == 24:
            all_asked.set()
        all_asked.wait(30)
        return TriggerResponse(True, "x" * 1_000_000)

    def queued_answers() -> int:  # the most frames a client of the endpoint has queued, on /diagnostics
        clients = [status for status_name, status in diagnostics.statuses.items() if "client #" in status_name]
        return max((int(status_values(status)["queued frames"].split("/")[0]) for status in clients), default=0)

    service = ros_node.Service(name, Trigger, big)
    diagnostics = DiagnosticsInbox(ros_node, "/" + bridge.name)
    try:
        with RawWebSocket(bridge.websocket_port) as ws:
            ws.command("__ros_service", topic=name, message_name="std_srvs/Trigger")
            ws.sync()
            for srv_id in range(24):
                ws.command("__request", srv_id=srv_id)
                ws.send_frame(name, b"")
            wait_for(lambda: len(answered) == 24, 30, "the 24 calls answered")
            # the answers on their way back; the ping once more than the budget of them waits in the client's queue
            wait_for(lambda: queued_answers() >= 5, 30, "5 answers of 1 MB (over 4 MiB) queued for the client")
            ws.send_event(Ping(b"answer me"))
            wait_for(lambda: "WebSocket pong not sent" in bridge.output(), 10, "the dropped pong in the log")
            warning = ws.wait_frame(
                lambda frame: frame.destination == "__warn" and b"WebSocket pong(s) not sent" in frame.payload,
                "the warning",
                30,
            )
            assert b"bytes of earlier answers waited unread" in warning.payload
            while len([frame for frame in ws.received if frame.destination == name]) < 24:  # no answer lost
                ws.next_frame(30)
            assert ws.pongs == 0
            ws.send_event(Ping(b"read now"))  # read everything: the budget is free again
            ws.sync()
            assert ws.pongs == 1
    finally:
        diagnostics.close()
        service.shutdown()


# --- the close handshake -------------------------------------------------------------------------------------------


def test_a_shutdown_close_follows_the_message_on_the_wire_and_nothing_follows_it(roscore, ros_node, tmp_path) -> None:
    """The endpoint stops while a client that reads nothing has a backlog of 1 MB messages, one of them half on the
    wire, and more keep coming: the client then reads whole messages, the goodbye and the Close (1001), and not one
    byte of WebSocket after it; it answers, and the endpoint closes the connection."""
    endpoint = start_endpoint(roscore, tmp_path, "--websocket-port", "0")
    topic = unique("ws_closing")
    publisher = ros_node.Publisher(topic, String, queue_size=100)
    ws = RawWebSocket(endpoint.websocket_port, timeout=30)
    try:
        ws.command("__subscribe", topic=topic, message_name="std_msgs/String", queue_size=50)
        ws.sync()
        wait_for(lambda: publisher.get_num_connections() == 1, 10, "the endpoint's subscriber")
        for index in range(40):
            publisher.publish(String(data=f"{index:06d}" + "x" * 1_000_000))
        wait_for(lambda: unsent_by_endpoint(ws) > 0, 10, "a message half on the wire")
        endpoint.process.send_signal(signal.SIGTERM)
        ws.wait_closed(30)
        assert ws.close_code == 1001, (ws.close_code, ws.close_reason)
        assert ws.received[-1].destination == "__warn" and b"shutting down" in ws.received[-1].payload
        ws.wait_eof(10)
        assert ws.after_close == 0
        assert all(frame.payload.endswith(b"x" * 100) for frame in ws.received if frame.destination == topic)
        endpoint.process.wait(10)
    finally:
        ws.sock.close()
        publisher.unregister()
        endpoint.stop()


def unsent_by_endpoint(ws: RawWebSocket) -> int:
    """Bytes the client has not read yet (its receive queue): the endpoint is writing to a full connection."""
    import fcntl
    import struct
    import termios

    return struct.unpack("i", fcntl.ioctl(ws.sock.fileno(), termios.FIONREAD, b"\0\0\0\0"))[0]


@pytest.mark.parametrize("answers", [True, False])
def test_the_endpoint_waits_for_the_peers_close_before_it_hangs_up(bridge, answers: bool) -> None:
    """A close of the endpoint's own (here for broken framing): it keeps the connection open for the client's
    answer; one that answers is hung up on at once, one that does not after the close timeout (said in the log)."""
    with RawWebSocket(bridge.websocket_port, answer_close=False) as ws:
        port = ws.sock.getsockname()[1]
        ws.send_message(b"\x04\x00\x00\x00/big" + (2**31 - 2).to_bytes(4, "little"))
        ws.wait_closed()
        assert ws.close_code == 1008 and not ws.eof
        readable = select.poll()
        readable.register(ws.sock, select.POLLIN)
        assert not readable.poll(500)  # the endpoint waits: no hang-up yet (it waits 2 s)
        if answers:
            from wsproto.events import CloseConnection

            ws.send_event(CloseConnection(code=1008))
        ws.wait_eof(10)
        assert ws.after_close == 0
    unanswered = f"127.0.0.1:{port}: no answer to the WebSocket close"
    wait_for(lambda: f"127.0.0.1:{port} disconnected" in bridge.output(), 10, "the disconnect's log line")
    assert (unanswered in bridge.output()) is not answers


# --- bad input ----------------------------------------------------------------------------------------------------


def test_a_bad_frame_in_a_message_gets_an_error_and_the_connection_goes_on(bridge) -> None:
    with RawWebSocket(bridge.websocket_port) as ws:
        ws.send_frame("__subscribe", b"{not json")
        ws.expect_error("__subscribe")
        ws.sync()
        assert ws.close_code is None and not ws.closed


def test_a_text_message_is_refused_and_the_connection_goes_on(bridge) -> None:
    from wsproto.events import TextMessage

    with RawWebSocket(bridge.websocket_port) as ws:
        ws.send_event(TextMessage(data='{"op": "subscribe"}'))
        assert "binary" in ws.expect_error("text WebSocket message")
        ws.sync()
        assert not ws.closed


@pytest.mark.parametrize(
    "what, send, said",
    [
        (
            "an oversized frame",
            lambda ws: ws.send_message(b"\x04\x00\x00\x00/big" + (2**31 - 2).to_bytes(4, "little")),
            "exceeds",
        ),
        (
            "a message ending inside a frame",
            lambda ws: ws.send_message(protocol.encode_frame("/topic", b"abcdef")[:-3]),
            "ended inside a ROS-TCP frame",
        ),
    ],
)
def test_broken_framing_is_said_then_closed(bridge, what, send, said) -> None:
    with RawWebSocket(bridge.websocket_port) as ws:
        send(ws)
        error = ws.expect_error(said)
        ws.wait_closed()
        assert ws.close_code == 1008, (what, error, ws.close_code, ws.close_reason)
        assert said in (ws.close_reason or ""), ws.close_reason
    with RawWebSocket(bridge.websocket_port) as ws:  # the endpoint serves on
        ws.sync()


def test_unmasked_websocket_frames_close_the_connection(bridge) -> None:
    """A client's frames must be masked (RFC 6455 5.1): a frame that is not is broken framing."""
    frame = protocol.encode_frame("/topic", b"abc")
    with RawWebSocket(bridge.websocket_port) as ws:
        ws.send_bytes(bytes((0x82, len(frame))) + frame)
        assert "broken WebSocket framing" in ws.expect_error("broken WebSocket framing")
        ws.wait_closed()
        assert ws.close_code == 1002


def test_a_close_in_the_middle_of_a_frame_ends_only_that_client(bridge, ros_node) -> None:
    from wsproto.events import CloseConnection

    topic = unique("ws_mid_frame")
    with RawWebSocket(bridge.websocket_port) as other:
        other.command("__subscribe", topic=topic, message_name="std_msgs/String")
        other.sync()
        with RawWebSocket(bridge.websocket_port) as ws:
            ws.send_message(protocol.encode_frame(topic, b"x" * 1000)[:500], finished=False)
            ws.send_event(CloseConnection(code=1000, reason="bye"))
            ws.wait_closed()
            assert ws.close_code == 1000  # the endpoint answered the close
        wait_for(lambda: "in the middle of a frame" in bridge.output(), 10, "the endpoint's log of the close")
        publisher = ros_node.Publisher(topic, String, queue_size=10)
        wait_for(lambda: publisher.get_num_connections() == 1, 10, "the endpoint's subscriber")
        publisher.publish(String(data="still served"))
        assert other.wait_frame(lambda frame: frame.destination == topic, topic).payload == serialize(
            String(data="still served")
        )
        publisher.unregister()


@pytest.mark.parametrize(
    "request_bytes",
    [
        b"GET / HTTP/1.1\r\nHost: x\r\n\r\n",  # plain HTTP, no upgrade
        protocol.encode_syscommand("__subscribe", {"topic": "/a", "message_name": "std_msgs/String"}),  # raw ROS-TCP
        b"\xff" * 100 + b"\r\n\r\n",  # not HTTP
    ],
)
def test_what_is_not_a_websocket_upgrade_is_answered_and_closed(bridge, request_bytes) -> None:
    with RawWebSocket(bridge.websocket_port, upgrade=False) as ws:
        ws.send_bytes(request_bytes)
        ws.sock.settimeout(10)
        answer = b""
        while True:
            data = ws.sock.recv(65536)
            if not data:
                break
            answer += data
        assert answer.startswith(b"HTTP/1.1 400"), answer[:200]
    with RawWebSocket(bridge.websocket_port) as ws:
        ws.sync()


def test_deadlines_auth_and_limits_hold_over_websocket(roscore, ros_node, tmp_path) -> None:
    endpoint = start_endpoint(
        roscore,
        tmp_path,
        "--websocket-port",
        "0",
        "--frame-timeout",
        "1",
        "--auth-token",
        "secret",
        "--max-clients",
        "2",
    )
    try:
        # no upgrade request at all: an HTTP 408 after --frame-timeout, and closed
        with RawWebSocket(endpoint.websocket_port, upgrade=False) as silent:
            silent.sock.settimeout(10)
            answer = silent.sock.recv(1000)
            assert answer.startswith(b"HTTP/1.1 408") and b"--frame-timeout" in answer, answer
            assert silent.sock.recv(100) == b""
        # the token is checked as over TCP
        with RawWebSocket(endpoint.websocket_port) as ws:
            ws.command("__subscribe", topic="/x", message_name="std_msgs/String")
            assert "authentication required" in ws.expect_error("authentication required")
            ws.wait_closed()
            assert ws.close_code == 1008
        with ws_client(endpoint, reconnect=False, auth_token="secret") as client:
            assert client.topic_list() is not None
            with RawConnection(endpoint.port) as tcp:
                # the third client is turned away with an HTTP 503 that says why
                with pytest.raises(Exception, match="503"):
                    RawWebSocket(endpoint.websocket_port)
                tcp.close()
    finally:
        endpoint.stop()


def test_without_wsproto_the_endpoint_runs_and_websocket_port_says_what_to_install(roscore, tmp_path) -> None:
    """wsproto made unimportable in the endpoint's own process (sys.modules entry None)."""
    launcher = (
        "import runpy, sys; sys.modules['wsproto'] = None; sys.argv[0] = 'bridge'; "
        "runpy.run_module('bridge', run_name='__main__', alter_sys=True)"
    )
    env = {**roscore.env, "PYTHONPATH": str(REPO)}
    node = f"no_wsproto_{os.getpid()}"
    asked = subprocess.run(
        [PYTHON, "-c", launcher, "--tcp-port", "0", "--websocket-port", "0", "--node-name", node],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert asked.returncode == 2, asked.stderr
    lines = [line for line in asked.stderr.splitlines() if line.startswith("python -m bridge")]
    assert len(lines) == 1 and "python3-wsproto" in lines[0] and "--websocket-port" in lines[0], asked.stderr
    plain = ManagedProcess(
        [PYTHON, "-c", launcher, "--tcp-port", "0", "--node-name", node + "_tcp"], env, tmp_path, "no_wsproto"
    )
    try:
        output = plain.wait_for_output("listening on", timeout=30)
        port = int(next(line for line in output.splitlines() if "listening on" in line).rsplit(":", 1)[1])
        with RawConnection(port) as tcp:
            tcp.sync()
    finally:
        plain.stop()
