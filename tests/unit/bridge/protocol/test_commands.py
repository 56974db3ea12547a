"""bridge.protocol.commands and framing's encode_frame, pure: the exact bytes of every event and frame."""

from __future__ import annotations

import json
import struct

import pytest

from bridge import protocol
from bridge.protocol import (
    Auth,
    Error,
    Event,
    Keepalive,
    LocalProtocolError,
    Log,
    Ping,
    PingResponse,
    Publish,
    Remove,
    RosService,
    ServiceRequest,
    ServiceResponse,
    Subscribe,
    TopicList,
    TopicListQuery,
    TopicMessage,
    UnityService,
    Warn,
    encode,
    encode_frame,
)


def u32(value: int) -> bytes:
    return struct.pack("<I", value)


def raw_frame(destination: bytes, payload: bytes) -> bytes:
    return u32(len(destination)) + destination + u32(len(payload)) + payload


# --- encoding: exact bytes ------------------------------------------------------------------------------------


def test_encode_frame_exact_bytes() -> None:
    assert encode_frame("/t", b"ab") == b"\x02\x00\x00\x00/t\x02\x00\x00\x00ab"
    assert encode_frame("/ü", b"") == b"\x03\x00\x00\x00/\xc3\xbc\x00\x00\x00\x00"  # length counts UTF-8 bytes


def test_handshake_exact_bytes() -> None:
    # The original v0.7.0 endpoint writes json.dumps({"version": ..., "metadata": json.dumps({"protocol": "ROS1"})})
    # with json.dumps' default spacing, outer and inner; Unity parses the outer object and then that string.
    body = b'{"version": "v0.7.0", "metadata": "{\\"protocol\\": \\"ROS1\\"}"}'
    assert protocol.handshake() == raw_frame(b"__handshake", body)
    params = json.loads(body)
    assert params["version"].startswith("v0.7.") and json.loads(params["metadata"]) == {"protocol": "ROS1"}


@pytest.mark.parametrize(
    ("event", "destination", "payload"),
    [
        (
            Publish("/t", "std_msgs/String"),
            b"__publish",
            b'{"topic":"/t","message_name":"std_msgs/String","queue_size":10,"latch":false}',
        ),
        (Subscribe("/t", "std_msgs/String"), b"__subscribe", b'{"topic":"/t","message_name":"std_msgs/String"}'),
        (
            Subscribe("/t", "std_msgs/String", 1),
            b"__subscribe",
            b'{"topic":"/t","message_name":"std_msgs/String","queue_size":1}',
        ),
        (RosService("/s", "std_srvs/SetBool"), b"__ros_service", b'{"topic":"/s","message_name":"std_srvs/SetBool"}'),
        (
            UnityService("/u", "std_srvs/Trigger"),
            b"__unity_service",
            b'{"topic":"/u","message_name":"std_srvs/Trigger"}',
        ),
        (Remove("unity_service", "/u"), b"__remove_unity_service", b'{"topic":"/u"}'),
        (TopicListQuery(), b"__topic_list", b"{}"),
        (
            TopicList(("/a", "/b"), ("std_msgs/String", "std_msgs/Empty")),
            b"__topic_list",
            b'{"topics":["/a","/b"],"types":["std_msgs/String","std_msgs/Empty"]}',
        ),
        (Auth("s3cret"), b"__auth", b'{"token":"s3cret"}'),
        (Ping("2026-11-23T04:00:00.0000000Z"), b"__ping", b'{"request_time":"2026-11-23T04:00:00.0000000Z"}'),
        (PingResponse("t0"), b"__ping_response", b'{"request_time":"t0"}'),
        (PingResponse("t0", 1700000000.25), b"__ping_response", b'{"request_time":"t0","ros_time":1700000000.25}'),
        (Error("bad"), b"__error", b'{"text":"bad"}'),
        (Error("bad", 101), b"__error", b'{"text":"bad","srv_id":101}'),
        (Warn("w"), b"__warn", b'{"text":"w"}'),
        (Log("l"), b"__log", b'{"text":"l"}'),
        (TopicMessage("/t", b"\x01\x02"), b"/t", b"\x01\x02"),
        (Keepalive(), b"", b""),
    ],
)
def test_events_encode_compactly_in_unitys_field_order(event: Event, destination: bytes, payload: bytes) -> None:
    assert encode(event) == raw_frame(destination, payload)


def test_a_service_event_is_its_header_and_body_back_to_back() -> None:
    assert encode(ServiceRequest(101, "/srv", b"rq")) == raw_frame(b"__request", b'{"srv_id":101}') + raw_frame(
        b"/srv", b"rq"
    )
    assert encode(ServiceResponse(1001, "/srv", b"")) == raw_frame(b"__response", b'{"srv_id":1001}') + raw_frame(
        b"/srv", b""
    )


def test_encode_syscommand_writes_any_json_but_only_to_a_command() -> None:
    assert protocol.encode_syscommand("__x", {"b": 1, "a": [2]}) == raw_frame(b"__x", b'{"b":1,"a":[2]}')
    with pytest.raises(LocalProtocolError, match="must start with '__'"):
        protocol.encode_syscommand("subscribe", {})
