"""bridge.protocol, pure: framing (FrameDecoder, encode_frame), the handshake bytes and parse_syscommand."""
from __future__ import annotations

import json
import struct
import tracemalloc

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bridge import protocol
from bridge.protocol import (
    Auth,
    BadFrame,
    Frame,
    FrameDecoder,
    FramingError,
    ProtocolError,
    Publish,
    Remove,
    Request,
    Response,
    RosService,
    Subscribe,
    TopicList,
    UnityService,
    encode_frame,
    parse_syscommand,
)


def u32(value: int) -> bytes:
    return struct.pack("<I", value)


def raw_frame(destination: bytes, payload: bytes) -> bytes:
    return u32(len(destination)) + destination + u32(len(payload)) + payload


def feed_in_pieces(decoder: FrameDecoder, stream: bytes, cuts: list[int]) -> list:
    items = []
    start = 0
    for cut in sorted(set(cuts)) + [len(stream)]:
        items += decoder.feed(stream[start:cut])
        start = cut
    return items


# --- framing: property tests ----------------------------------------------------------------------------------

# Destinations as a real client writes them: UTF-8, no trailing NUL (those are stripped), within the 1 KiB limit.
destinations = st.text(st.characters(blacklist_categories=("Cs",)), max_size=40).filter(
    lambda text: not text.endswith("\0")
)
frames_strategy = st.lists(
    st.builds(Frame, destinations, st.binary(max_size=300)), min_size=1, max_size=25
)


@settings(max_examples=300, deadline=None)
@given(frames=frames_strategy, data=st.data())
def test_any_split_of_a_stream_decodes_to_the_same_frames(frames: list[Frame], data) -> None:
    stream = b"".join(encode_frame(frame.destination, frame.payload) for frame in frames)
    cuts = data.draw(st.lists(st.integers(0, len(stream)), max_size=60))
    decoder = FrameDecoder()
    assert feed_in_pieces(decoder, stream, cuts) == frames
    assert decoder.buffered_bytes == 0


@settings(max_examples=40, deadline=None)
@given(frames=frames_strategy)
def test_one_byte_at_a_time_and_all_at_once_agree(frames: list[Frame]) -> None:
    stream = b"".join(encode_frame(frame.destination, frame.payload) for frame in frames)
    one_by_one = FrameDecoder()
    items = []
    for index in range(len(stream)):
        items += one_by_one.feed(stream[index : index + 1])
    assert items == frames
    assert FrameDecoder().feed(stream) == frames


@settings(max_examples=100, deadline=None)
@given(frames=frames_strategy, data=st.data())
def test_incomplete_tail_stays_buffered_until_completed(frames: list[Frame], data) -> None:
    stream = b"".join(encode_frame(frame.destination, frame.payload) for frame in frames)
    cut = data.draw(st.integers(0, len(stream) - 1))
    decoder = FrameDecoder()
    first = decoder.feed(stream[:cut])
    assert first == frames[: len(first)] and len(first) < len(frames)
    assert first + decoder.feed(stream[cut:]) == frames


def test_keepalive_is_eight_zero_bytes_and_recognised() -> None:
    assert protocol.KEEPALIVE_FRAME == b"\0" * 8
    (frame,) = FrameDecoder().feed(b"\0" * 8)
    assert frame == Frame("", b"") and frame.is_keepalive and not frame.is_syscommand
    assert not Frame("", b"x").is_keepalive
    assert Frame("__subscribe", b"{}").is_syscommand and not Frame("/t", b"").is_syscommand


def test_trailing_nuls_in_destinations_are_stripped() -> None:
    stream = raw_frame(b"/joint_states\0\0", b"abc") + raw_frame(b"__topic_list\0", b"{}")
    assert FrameDecoder().feed(stream) == [Frame("/joint_states", b"abc"), Frame("__topic_list", b"{}")]


def test_non_utf8_destination_is_a_bad_frame_and_the_stream_continues() -> None:
    decoder = FrameDecoder()
    stream = raw_frame(b"/bad\xff\xfe", b"payload") + encode_frame("/good", b"ok")
    bad, good = decoder.feed(stream)
    assert isinstance(bad, BadFrame) and "UTF-8" in bad.reason and "bad" in bad.reason
    assert good == Frame("/good", b"ok")
    assert decoder.feed(encode_frame("/next", b"")) == [Frame("/next", b"")]


# --- framing: limits before allocation ------------------------------------------------------------------------


def test_huge_payload_length_fails_as_soon_as_the_header_is_complete_without_allocating() -> None:
    header = u32(5) + b"/huge" + u32(0xFFFFFFF0)
    decoder = FrameDecoder()
    tracemalloc.start()
    try:
        for byte in header[:-1]:
            assert decoder.feed(bytes([byte])) == []
        with pytest.raises(FramingError) as raised:
            decoder.feed(header[-1:])
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20, f"decoder allocated {peak} bytes for a refused frame"
    message = str(raised.value)
    assert str(0xFFFFFFF0) in message and "/huge" in message and "limit" in message


def test_payload_limit_is_configurable_and_exact() -> None:
    decoder = FrameDecoder(max_payload_bytes=10)
    assert decoder.feed(encode_frame("/t", b"x" * 10)) == [Frame("/t", b"x" * 10)]
    with pytest.raises(FramingError, match="11"):
        decoder.feed(u32(2) + b"/t" + u32(11))


def test_oversized_destination_fails_on_its_length_prefix_alone() -> None:
    decoder = FrameDecoder()
    prefix = u32(protocol.MAX_DESTINATION_BYTES + 1)
    assert decoder.feed(prefix[:3]) == []
    with pytest.raises(FramingError, match="destination length 1025"):
        decoder.feed(prefix[3:])  # only the 4-byte prefix has arrived


def test_destination_exactly_at_the_limit_is_accepted() -> None:
    destination = "/" + "d" * (protocol.MAX_DESTINATION_BYTES - 1)
    assert FrameDecoder().feed(encode_frame(destination, b"")) == [Frame(destination, b"")]


def test_decoder_refuses_input_after_a_framing_error() -> None:
    decoder = FrameDecoder(max_payload_bytes=4)
    with pytest.raises(FramingError):
        decoder.feed(encode_frame("/t", b"12345"))
    assert decoder.buffered_bytes == 0
    with pytest.raises(FramingError):
        decoder.feed(encode_frame("/t", b"ok"))
    with pytest.raises(FramingError):
        decoder.feed(b"")


def test_framing_error_is_a_protocol_error() -> None:
    assert issubclass(FramingError, ProtocolError) and issubclass(ProtocolError, ValueError)


# --- encoding: exact bytes ------------------------------------------------------------------------------------


def test_encode_frame_exact_bytes() -> None:
    assert encode_frame("/t", b"ab") == b"\x02\x00\x00\x00/t\x02\x00\x00\x00ab"
    assert encode_frame("/ü", b"") == b"\x03\x00\x00\x00/\xc3\xbc\x00\x00\x00\x00"  # length counts UTF-8 bytes


def test_handshake_exact_bytes() -> None:
    # The original v0.7.0 endpoint writes json.dumps({"version": ..., "metadata": json.dumps({"protocol": "ROS1"})})
    # with json.dumps' default spacing, outer and inner; Unity parses the outer object and then that string.
    body = b'{"version": "v0.7.0", "metadata": "{\\"protocol\\": \\"ROS1\\"}"}'
    assert protocol.handshake_frame() == raw_frame(b"__handshake", body)
    params = json.loads(body)
    assert params["version"].startswith("v0.7.") and json.loads(params["metadata"]) == {"protocol": "ROS1"}


def test_syscommand_encoding_is_compact_and_keeps_field_order() -> None:
    frame = protocol.encode_syscommand(
        "__publish", {"topic": "/t", "message_name": "std_msgs/String", "queue_size": 10, "latch": False}
    )
    assert frame == raw_frame(
        b"__publish", b'{"topic":"/t","message_name":"std_msgs/String","queue_size":10,"latch":false}'
    )
    assert protocol.error_frame("bad") == raw_frame(b"__error", b'{"text":"bad"}')
    assert protocol.warn_frame("w") == raw_frame(b"__warn", b'{"text":"w"}')
    assert protocol.log_frame("l") == raw_frame(b"__log", b'{"text":"l"}')
    with pytest.raises(ProtocolError, match="must start with '__'"):
        protocol.encode_syscommand("subscribe", {})


# --- system commands ------------------------------------------------------------------------------------------


def command(destination: str, payload: bytes | str | dict) -> Frame:
    if isinstance(payload, dict):
        payload = json.dumps(payload)
    if isinstance(payload, str):
        payload = payload.encode()
    return Frame(destination, payload)


@pytest.mark.parametrize(
    ("destination", "params", "expected"),
    [
        ("__subscribe", {"topic": "/t", "message_name": "std_msgs/String"}, Subscribe("/t", "std_msgs/String")),
        (
            "__publish",
            {"topic": "/t", "message_name": "sensor_msgs/JointState", "queue_size": 3, "latch": True},
            Publish("/t", "sensor_msgs/JointState", 3, True),
        ),
        ("__publish", {"topic": "t", "message_name": "std_msgs/Empty"}, Publish("t", "std_msgs/Empty", 10, False)),
        ("__ros_service", {"topic": "/srv", "message_name": "std_srvs/SetBool"}, RosService("/srv", "std_srvs/SetBool")),
        ("__unity_service", {"topic": "/u", "message_name": "std_srvs/Trigger"}, UnityService("/u", "std_srvs/Trigger")),
        ("__request", {"srv_id": 101}, Request(101)),
        ("__response", {"srv_id": 1001}, Response(1001)),
        ("__topic_list", {}, TopicList()),
        ("__remove_subscriber", {"topic": "/t"}, Remove("subscriber", "/t")),
        ("__remove_publisher", {"topic": "/t"}, Remove("publisher", "/t")),
        ("__remove_ros_service", {"topic": "/srv"}, Remove("ros_service", "/srv")),
        ("__remove_unity_service", {"topic": "/u"}, Remove("unity_service", "/u")),
        ("__auth", {"token": "s3cret"}, Auth("s3cret")),
    ],
)
def test_every_command_parses(destination: str, params: dict, expected) -> None:
    assert parse_syscommand(command(destination, params)) == expected


def test_topic_list_accepts_an_empty_payload() -> None:
    assert parse_syscommand(Frame("__topic_list", b"")) == TopicList()


def test_client_commands_cover_the_table() -> None:
    assert protocol.CLIENT_COMMANDS == {
        "__subscribe", "__publish", "__ros_service", "__unity_service", "__request", "__response",
        "__topic_list", "__auth", "__remove_subscriber", "__remove_publisher", "__remove_ros_service",
        "__remove_unity_service",
    }


def rejects(frame: Frame, *fragments: str) -> str:
    with pytest.raises(ProtocolError) as raised:
        parse_syscommand(frame)
    message = str(raised.value)
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"
    return message


def test_unknown_command_is_named() -> None:
    rejects(command("__frobnicate", {}), "unknown system command", "__frobnicate")
    rejects(command("__handshake", {"version": "v0.7.0"}), "unknown system command", "__handshake")


def test_malformed_json_names_the_command() -> None:
    rejects(command("__subscribe", '{"topic": "/t",'), "__subscribe", "malformed JSON")


def test_non_utf8_payload_names_the_command() -> None:
    rejects(Frame("__subscribe", b"\xff{}"), "__subscribe", "UTF-8")


@pytest.mark.parametrize("payload", ["[1, 2]", '"text"', "3", "null"])
def test_non_object_json_is_refused(payload: str) -> None:
    rejects(command("__topic_list", payload), "__topic_list", "must be a JSON object")


@pytest.mark.parametrize(
    ("destination", "params", "field"),
    [
        ("__subscribe", {"topic": "/t"}, "message_name"),
        ("__subscribe", {"message_name": "std_msgs/String"}, "topic"),
        ("__publish", {"topic": "/t"}, "message_name"),
        ("__request", {}, "srv_id"),
        ("__response", {}, "srv_id"),
        ("__auth", {}, "token"),
        ("__remove_subscriber", {}, "topic"),
        ("__remove_unity_service", {}, "topic"),
    ],
)
def test_missing_field_is_named(destination: str, params: dict, field: str) -> None:
    rejects(command(destination, params), destination, "missing field", repr(field))


@pytest.mark.parametrize(
    ("destination", "params", "field"),
    [
        ("__subscribe", {"topic": "/t", "message_name": "std_msgs/String", "queue_size": 1}, "queue_size"),
        ("__topic_list", {"verbose": True}, "verbose"),
        ("__request", {"srv_id": 1, "topic": "/s"}, "topic"),
        ("__remove_publisher", {"topic": "/t", "latch": False}, "latch"),
    ],
)
def test_extra_field_is_named(destination: str, params: dict, field: str) -> None:
    rejects(command(destination, params), destination, "unexpected field", repr(field))


@pytest.mark.parametrize(
    ("destination", "params", "field"),
    [
        ("__request", {"srv_id": True}, "srv_id"),  # bool is not an int, although Python says it is
        ("__response", {"srv_id": False}, "srv_id"),
        ("__request", {"srv_id": "101"}, "srv_id"),
        ("__request", {"srv_id": 101.0}, "srv_id"),
        ("__publish", {"topic": "/t", "message_name": "std_msgs/String", "queue_size": True}, "queue_size"),
        ("__publish", {"topic": "/t", "message_name": "std_msgs/String", "queue_size": "10"}, "queue_size"),
        ("__publish", {"topic": "/t", "message_name": "std_msgs/String", "latch": 1}, "latch"),
        ("__subscribe", {"topic": 5, "message_name": "std_msgs/String"}, "topic"),
        ("__subscribe", {"topic": "/t", "message_name": ["std_msgs/String"]}, "message_name"),
        ("__auth", {"token": 1234}, "token"),
    ],
)
def test_wrong_type_is_named(destination: str, params: dict, field: str) -> None:
    rejects(command(destination, params), destination, f"field {field!r} must be")


def test_negative_queue_size_is_refused() -> None:
    rejects(
        command("__publish", {"topic": "/t", "message_name": "std_msgs/String", "queue_size": -1}),
        "__publish", "queue_size",
    )


@pytest.mark.parametrize("topic", ["", "__hidden", "/with space", "/tab\there", "/nul\0", "/new\nline"])
@pytest.mark.parametrize("destination", ["__subscribe", "__publish", "__ros_service", "__unity_service"])
def test_bad_topic_is_named(destination: str, topic: str) -> None:
    rejects(command(destination, {"topic": topic, "message_name": "std_msgs/String"}), destination, "'topic'")


def test_bad_topic_in_remove_is_named() -> None:
    rejects(command("__remove_subscriber", {"topic": ""}), "__remove_subscriber", "'topic'")


@pytest.mark.parametrize(
    "message_name",
    ["String", "std_msgs/", "/String", "std_msgs/msg/String", "std msgs/String", "std_msgs/Str-ing", "", "a/b/c"],
)
def test_bad_message_name_is_named(message_name: str) -> None:
    rejects(command("__subscribe", {"topic": "/t", "message_name": message_name}), "__subscribe", "'message_name'")


@pytest.mark.parametrize("message_name", ["std_msgs/String", "sensor_msgs/JointState", "tf2_msgs/TFMessage"])
def test_good_message_names_pass(message_name: str) -> None:
    assert parse_syscommand(command("__subscribe", {"topic": "/t", "message_name": message_name})).message_name == message_name


def test_parse_json_params_for_endpoint_commands() -> None:
    assert protocol.parse_json_params("__error", b'{"text":"x"}') == {"text": "x"}
    with pytest.raises(ProtocolError, match="__error"):
        protocol.parse_json_params("__error", b"[")
