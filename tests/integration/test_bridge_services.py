"""Services through a real endpoint: client -> ROS (__ros_service/__request) and ROS -> client (__unity_service)."""

from __future__ import annotations

import json
import threading
import time

import pytest
from std_msgs.msg import String
from std_srvs.srv import SetBool, SetBoolRequest, SetBoolResponse, Trigger, TriggerRequest, TriggerResponse

from bridge import protocol
from bridge.client import ClientError
from measuring.endpoint import settled
from measuring.procfs import figures
from tests.integration.bridge_helpers import (
    RawConnection,
    RosInbox,
    bridge,  # noqa: F401 - module-scoped endpoint fixture (service timeout 2 s)
    serialize,
    service_exists,
    start_endpoint,
    tcp_client,
    unique,
)
from tests.rosenv import wait_for

pytestmark = pytest.mark.lane("endpoint", on=("noetic",))


def set_bool_service(rospy, name: str, calls: list | None = None):
    def handle(request: SetBoolRequest) -> SetBoolResponse:
        if calls is not None:
            calls.append(request.data)
        return SetBoolResponse(success=not request.data, message=f"got {request.data}")

    service = rospy.Service(name, SetBool, handle)
    return service


class BackgroundCall:
    """One rospy service call on its own thread (the test meanwhile plays the client that answers it);
    `outcome` is the response or the exception."""

    def __init__(self, rospy, name: str, service_class=Trigger, *request_args) -> None:
        self.outcome: object = None
        self._thread = threading.Thread(target=self._run, args=(rospy, name, service_class, request_args), daemon=True)
        self._thread.start()

    def _run(self, rospy, name: str, service_class, request_args: tuple) -> None:
        try:
            self.outcome = rospy.ServiceProxy(name, service_class)(*request_args)
        except Exception as error:  # rospy.ServiceException
            self.outcome = error

    def finished(self, timeout: float = 10.0) -> bool:
        self._thread.join(timeout)
        return not self._thread.is_alive()


def test_client_calls_a_ros_service(bridge, ros_node) -> None:
    name = unique("set_bool")
    calls: list[bool] = []
    service = set_bool_service(ros_node, name, calls)
    with tcp_client(bridge.port, reconnect=False) as client:
        client.register_ros_service(name, "std_srvs/SetBool")
        for data in (True, False, True):
            response = client.call_service(name, serialize(SetBoolRequest(data=data)), timeout=10)
            assert response == serialize(SetBoolResponse(success=not data, message=f"got {data}"))
        assert calls == [True, False, True] and client.errors == []
    service.shutdown()


def test_ros_service_response_wire_format(bridge, ros_node) -> None:
    """__response {"srv_id": <the client's id>} and the body, destination = service, back to back."""
    name = unique("set_bool_raw")
    service = set_bool_service(ros_node, name)
    with RawConnection(bridge.port) as client:
        client.command("__ros_service", topic=name, message_name="std_srvs/SetBool")
        for srv_id, data in ((101, True), (102, False)):
            client.send(
                b"".join(
                    (
                        protocol.encode_syscommand("__request", {"srv_id": srv_id}),
                        protocol.encode_frame(name, serialize(SetBoolRequest(data))),
                    )
                )
            )
            header = client.wait_frame(lambda f: f.destination == "__response", "__response")
            assert json.loads(header.payload) == {"srv_id": srv_id}
            body = client.next_frame()
            assert body.destination == name
            assert body.payload == serialize(SetBoolResponse(success=not data, message=f"got {data}"))
        assert client.errors() == []
    service.shutdown()


def test_ros_calls_a_client_implemented_service(bridge, ros_node) -> None:
    name = unique("client_trigger")
    requests: list[bytes] = []

    def handler(request: bytes) -> bytes:
        requests.append(request)
        return serialize(TriggerResponse(success=True, message=f"call {len(requests)}"))

    with tcp_client(bridge.port, reconnect=False) as client:
        client.implement_service(name, "std_srvs/Trigger", handler)
        wait_for(lambda: service_exists(ros_node, name), 10, f"{name} advertised by the endpoint")
        proxy = ros_node.ServiceProxy(name, Trigger)
        for index in (1, 2):
            response = proxy(TriggerRequest())
            assert (response.success, response.message) == (True, f"call {index}")
        assert requests == [b"", b""]
        proxy.close()


def test_ros_request_wire_format_and_setbool_both_ways(bridge, ros_node) -> None:
    name = unique("client_set_bool")
    with RawConnection(bridge.port) as client:
        client.offer_service(ros_node, name, "std_srvs/SetBool")
        caller = BackgroundCall(ros_node, name, SetBool, True)
        header = client.wait_frame(lambda f: f.destination == "__request", "__request")
        srv_id = json.loads(header.payload)["srv_id"]
        assert isinstance(srv_id, int) and srv_id >= 1001
        body = client.next_frame()
        assert body.destination == name and body.payload == serialize(SetBoolRequest(data=True))
        client.command("__response", srv_id=srv_id)
        client.send_frame(name, serialize(SetBoolResponse(success=True, message="from the client")))
        assert caller.finished()
        assert isinstance(caller.outcome, SetBoolResponse)
        assert (caller.outcome.success, caller.outcome.message) == (True, "from the client")
        client.sync()
        assert client.errors() == []


def test_failing_ros_service_gives_an_error_naming_it_and_the_connection_keeps_working(bridge, ros_node) -> None:
    name = unique("failing")

    def handle(request: SetBoolRequest) -> SetBoolResponse:
        if request.data:
            raise RuntimeError("deliberate failure")
        return SetBoolResponse(success=True, message="fine")

    service = ros_node.Service(name, SetBool, handle)
    with tcp_client(bridge.port, reconnect=False) as client:
        client.register_ros_service(name, "std_srvs/SetBool")
        with pytest.raises(ClientError) as raised:
            client.call_service(name, serialize(SetBoolRequest(data=True)), timeout=10)
        assert name in str(raised.value)
        assert any(name in text and "will not complete" in text for text in client.errors)
        response = client.call_service(name, serialize(SetBoolRequest(data=False)), timeout=10)
        assert response == serialize(SetBoolResponse(success=True, message="fine"))
        assert client.connections == 1
    service.shutdown()


def test_a_malformed_request_body_gets_an_error_and_never_reaches_the_ros_service(bridge, ros_node) -> None:
    name = unique("checked_request")
    calls: list = []
    service = set_bool_service(ros_node, name, calls)
    with RawConnection(bridge.port) as client:
        client.command("__ros_service", topic=name, message_name="std_srvs/SetBool")
        client.command("__request", srv_id=5)
        client.send_frame(name, b"\x01\x00")  # SetBool's request is one bool byte: a trailing byte
        text = client.expect_error("__request 5:", name, "std_srvs/SetBool request", "trailing")
        assert "not sent to ROS" in text
        client.command("__request", srv_id=6)  # the connection and its framing state are intact
        client.send_frame(name, serialize(SetBoolRequest(data=True)))
        client.wait_command("__response")
        assert client.next_frame().payload == serialize(SetBoolResponse(success=False, message="got True"))
        assert calls == [True]
    service.shutdown()


def test_the_tcp_client_hears_at_once_that_its_malformed_request_was_refused(bridge, ros_node) -> None:
    name = unique("checked_request_client")
    calls: list = []
    service = set_bool_service(ros_node, name, calls)
    with tcp_client(bridge.port, reconnect=False) as client:
        client.register_ros_service(name, "std_srvs/SetBool")
        with pytest.raises(ClientError, match="trailing"):
            client.call_service(name, b"\x01\x00", timeout=30)  # fails on the __error, not the 30 s timeout
        assert client.call_service(name, serialize(SetBoolRequest(data=False)), timeout=10) == serialize(
            SetBoolResponse(success=True, message="got False")
        )
    assert calls == [False]
    service.shutdown()


def test_an_invalid_response_from_the_client_fails_the_ros_call_with_a_reason(bridge, ros_node) -> None:
    name = unique("checked_response")
    with RawConnection(bridge.port) as client:
        client.offer_service(ros_node, name, "std_srvs/Trigger")
        caller = BackgroundCall(ros_node, name)
        srv_id = json.loads(client.wait_frame(lambda f: f.destination == "__request", "__request").payload)["srv_id"]
        client.next_frame()  # the request body
        client.command("__response", srv_id=srv_id)
        client.send_frame(name, b"\x01\x05\x00\x00\x00ok")  # the message string claims 5 bytes, has 2
        assert caller.finished()
        assert isinstance(caller.outcome, ros_node.ServiceException)
        assert "invalid response" in str(caller.outcome) and "truncated" in str(caller.outcome)
        client.expect_error(f"__response {srv_id}", "std_srvs/Trigger response", "truncated")
        client.sync()


def test_missing_ros_service_gives_an_error_naming_it(bridge, ros_node) -> None:
    missing, working = unique("missing"), unique("working")
    service = set_bool_service(ros_node, working)
    with tcp_client(bridge.port, reconnect=False) as client:
        client.register_ros_service(missing, "std_srvs/SetBool")
        client.register_ros_service(working, "std_srvs/SetBool")
        started = time.monotonic()
        with pytest.raises(ClientError, match="not available"):
            client.call_service(missing, serialize(SetBoolRequest(data=True)), timeout=10)
        assert time.monotonic() - started < 8  # the endpoint's --service-timeout is 2 s
        assert any(missing in text for text in client.errors)
        assert client.call_service(working, serialize(SetBoolRequest(data=True)), timeout=10) == serialize(
            SetBoolResponse(success=False, message="got True")
        )
        assert client.connections == 1
    service.shutdown()


def test_a_missing_service_is_named_missing_when_its_look_up_ends_past_the_deadline(ros_node) -> None:
    # The master's "no such service" can come back after the call's deadline (a slow master, a loaded machine):
    # the verdict is still that answer, not "did not answer". A deadline of 1 us has passed before any answer.
    from bridge.ros.raw_types import RosError
    from bridge.ros.service_proxy import RawServiceProxy

    missing = unique("late_missing")
    proxy = RawServiceProxy(SetBool, missing, max_response_bytes=1024)
    with pytest.raises(RosError, match=f"service {missing} is not available"):
        proxy.call(serialize(SetBoolRequest(data=True)), 1e-6, threading.Event())


def test_request_for_an_unregistered_service_is_refused(bridge) -> None:
    name = unique("unregistered")
    with RawConnection(bridge.port) as client:
        client.command("__request", srv_id=101)
        client.send_frame(name, serialize(SetBoolRequest(data=True)))
        text = client.expect_error("__request 101", name)
        assert "__ros_service" in text
        # The call's id is also a field of the __error, so a client fails that call without reading the text.
        (error,) = [json.loads(f.payload) for f in client.received if f.destination == "__error"]
        assert error == {"text": text, "srv_id": 101}
        client.sync()


def test_remove_ros_service(bridge, ros_node) -> None:
    name = unique("removed_ros_srv")
    service = set_bool_service(ros_node, name)
    with tcp_client(bridge.port, reconnect=False) as client:
        client.register_ros_service(name, "std_srvs/SetBool")
        client.call_service(name, serialize(SetBoolRequest(data=True)), timeout=10)
        client.remove("ros_service", name)
        with pytest.raises(ClientError, match="not registered"):
            client.call_service(name, serialize(SetBoolRequest(data=True)), timeout=10)
    service.shutdown()


def test_unknown_response_id_gives_an_error_and_the_next_frame_is_discarded(bridge, ros_node) -> None:
    topic = unique("after_bad_response")
    inbox = RosInbox(ros_node, topic)
    with RawConnection(bridge.port) as client:
        client.register_publisher(topic, "std_msgs/String")
        client.sync()
        inbox.wait_connected()
        client.command("__response", srv_id=987654)
        client.send_frame(topic, serialize(String("swallowed as the response body")))
        client.expect_error("__response", "987654", "discarded")
        client.send_frame(topic, serialize(String("published")))
        assert inbox.wait_count(1) == [serialize(String("published"))]
        client.sync()
        assert len(client.errors()) == 1
        assert inbox.snapshot() == [serialize(String("published"))]
    inbox.close()


def test_a_client_dying_mid_request_does_not_poison_the_next_client(bridge, ros_node) -> None:
    topic = unique("unpoisoned")
    inbox = RosInbox(ros_node, topic)
    with RawConnection(bridge.port) as dying:
        dying.sync()
        dying.command("__request", srv_id=101)  # its body never comes (the endpoint reads this before the EOF)
    with RawConnection(bridge.port) as client:
        client.register_publisher(topic, "std_msgs/String")
        client.sync()
        inbox.wait_connected()
        client.send_frame(topic, serialize(String("intact")))
        assert inbox.wait_count(1) == [serialize(String("intact"))]
        client.sync()
        assert client.errors() == []
    inbox.close()


def test_client_disconnecting_before_answering_fails_the_ros_call_quickly(bridge, ros_node) -> None:
    name = unique("abandoned")
    client = RawConnection(bridge.port)
    client.offer_service(ros_node, name, "std_srvs/Trigger")
    caller = BackgroundCall(ros_node, name)
    client.wait_frame(lambda f: f.destination == "__request", "__request")
    client.close()
    assert caller.finished()
    assert isinstance(caller.outcome, ros_node.ServiceException)
    wait_for(lambda: not service_exists(ros_node, name), 10, f"{name} withdrawn after the client left")


def test_reregistering_a_unity_service_moves_it_to_the_newest_client(bridge, ros_node) -> None:
    name = unique("moved_srv")
    with tcp_client(bridge.port, reconnect=False) as old, tcp_client(bridge.port, reconnect=False) as new:
        old.implement_service(name, "std_srvs/Trigger", lambda _: serialize(TriggerResponse(True, "old")))
        old.topic_list()
        new.implement_service(name, "std_srvs/Trigger", lambda _: serialize(TriggerResponse(True, "new")))
        new.topic_list()
        wait_for(lambda: service_exists(ros_node, name), 10, f"{name} advertised")
        assert ros_node.ServiceProxy(name, Trigger)().message == "new"


class HungService:
    """A rospy service in this process that answers only when released (at the end of the test)."""

    def __init__(self, rospy, name: str) -> None:
        self.release = threading.Event()
        self.started = 0
        self.service = rospy.Service(name, Trigger, self._handle)

    def _handle(self, request: TriggerRequest) -> TriggerResponse:
        self.started += 1
        self.release.wait(60)
        return TriggerResponse(success=True, message="late")

    def close(self) -> None:
        self.release.set()
        self.service.shutdown()


def test_a_ros_service_that_never_answers_fails_the_call_by_its_deadline(bridge, ros_node) -> None:
    name = unique("hung")
    hung = HungService(ros_node, name)
    try:
        with RawConnection(bridge.port) as client:
            client.command("__ros_service", topic=name, message_name="std_srvs/Trigger")
            started = time.monotonic()
            client.command("__request", srv_id=7)
            client.send_frame(name, b"")
            client.expect_error("__request 7", name, "did not answer within 2 s", timeout=10)
            assert time.monotonic() - started < 6  # the endpoint's --service-timeout is 2 s
            (error,) = [json.loads(f.payload) for f in client.received if f.destination == "__error"]
            assert error["srv_id"] == 7
            client.sync()
    finally:
        hung.close()


def test_calls_in_flight_never_hold_up_the_clients_other_commands(bridge, ros_node) -> None:
    name = unique("hung_many")
    hung = HungService(ros_node, name)
    try:
        with RawConnection(bridge.port) as client:
            client.command("__ros_service", topic=name, message_name="std_srvs/Trigger")
            for srv_id in range(10, 16):  # more than the client's own share of calls at once (--call-workers)
                client.command("__request", srv_id=srv_id)
                client.send_frame(name, b"")
            wait_for(lambda: hung.started >= 4, 10, "calls in flight")
            client.command("__topic_list")
            client.wait_command("__topic_list", timeout=1.5)  # before any call's 2 s deadline
            assert client.errors() == []
    finally:
        hung.close()


def test_calls_queued_behind_the_clients_workers_end_by_their_own_deadline(bridge, ros_node) -> None:
    # Three times the client's own share of calls at once (--call-workers): the deadline of each runs from its
    # asking, not from when it starts (once a call waited for a worker, and the third round's errors came at three
    # times the timeout).
    name = unique("hung_queued")
    hung = HungService(ros_node, name)
    try:
        with RawConnection(bridge.port) as client:
            client.command("__ros_service", topic=name, message_name="std_srvs/Trigger")
            client.sync()
            started = time.monotonic()
            for srv_id in range(12):
                client.command("__request", srv_id=srv_id)
                client.send_frame(name, b"")
            for _ in range(12):
                client.expect_error("__request", name, "this call will not complete", timeout=30)
            assert time.monotonic() - started < 2 + 2  # the endpoint's --service-timeout is 2 s
            ended = sorted(json.loads(f.payload)["srv_id"] for f in client.received if f.destination == "__error")
            assert ended == list(range(12))
    finally:
        hung.close()


def test_a_departed_clients_calls_end_with_it(roscore, ros_node, tmp_path) -> None:
    endpoint = start_endpoint(roscore, tmp_path, "--service-timeout", "60", name="departed_calls_endpoint")
    name = unique("hung_departed")
    hung = HungService(ros_node, name)
    try:
        settled(roscore, "/departed_calls_endpoint")
        baseline = figures(endpoint.pid).threads
        with RawConnection(endpoint.port) as client:
            client.command("__ros_service", topic=name, message_name="std_srvs/Trigger")
            for srv_id in range(4):
                client.command("__request", srv_id=srv_id)
                client.send_frame(name, b"")
            wait_for(lambda: hung.started >= 4, 10, "calls in flight")
            assert figures(endpoint.pid).threads > baseline
        wait_for(lambda: figures(endpoint.pid).threads <= baseline, 5, "the calls' threads to end (deadline is 60 s)")
    finally:
        hung.close()
        endpoint.stop()
