"""bridge.protocol.conversation, pure: the conversation of both roles (commands parsed and checked, service headers
paired with their bodies, errors local and remote, what each role may send)."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
import textwrap

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bridge import protocol
from bridge.protocol import (
    MAX_JSON_NESTING,
    Auth,
    Conversation,
    Error,
    Event,
    Handshake,
    IgnoredFields,
    InvalidInput,
    Keepalive,
    LocalProtocolError,
    Log,
    Ping,
    PingResponse,
    Publish,
    RemoteProtocolError,
    Remove,
    Role,
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


# --- the conversation, endpoint role: what a client says ------------------------------------------------------


def received(data: bytes, role: Role = Role.ENDPOINT) -> list:
    return Conversation(role).receive_data(data)


def command(destination: str, payload: bytes | str | dict) -> bytes:
    if isinstance(payload, dict):
        payload = json.dumps(payload)
    if isinstance(payload, str):
        payload = payload.encode()
    return encode_frame(destination, payload)


def parsed(destination: str, payload: bytes | str | dict) -> Event:
    (event,) = received(command(destination, payload))
    return event


@pytest.mark.parametrize(
    ("destination", "params", "expected"),
    [
        ("__subscribe", {"topic": "/t", "message_name": "std_msgs/String"}, Subscribe("/t", "std_msgs/String")),
        (
            "__subscribe",
            {"topic": "/t", "message_name": "std_msgs/String", "queue_size": 1},
            Subscribe("/t", "std_msgs/String", 1),
        ),
        (
            "__publish",
            {"topic": "/t", "message_name": "sensor_msgs/JointState", "queue_size": 3, "latch": True},
            Publish("/t", "sensor_msgs/JointState", 3, True),
        ),
        ("__publish", {"topic": "t", "message_name": "std_msgs/Empty"}, Publish("t", "std_msgs/Empty", 10, False)),
        (
            "__ros_service",
            {"topic": "/srv", "message_name": "std_srvs/SetBool"},
            RosService("/srv", "std_srvs/SetBool"),
        ),
        (
            "__unity_service",
            {"topic": "/u", "message_name": "std_srvs/Trigger"},
            UnityService("/u", "std_srvs/Trigger"),
        ),
        ("__topic_list", {}, TopicListQuery()),
        ("__remove_subscriber", {"topic": "/t"}, Remove("subscriber", "/t")),
        ("__remove_publisher", {"topic": "/t"}, Remove("publisher", "/t")),
        ("__remove_ros_service", {"topic": "/srv"}, Remove("ros_service", "/srv")),
        ("__remove_unity_service", {"topic": "/u"}, Remove("unity_service", "/u")),
        ("__auth", {"token": "s3cret"}, Auth("s3cret")),
        ("__ping", {"request_time": "2026-11-23T04:00:00.1234567Z"}, Ping("2026-11-23T04:00:00.1234567Z")),
    ],
)
def test_every_client_command_parses(destination: str, params: dict, expected: Event) -> None:
    assert parsed(destination, params) == expected


@settings(max_examples=100, deadline=None)
@given(
    event=st.one_of(
        st.builds(Subscribe, st.just("/t"), st.just("std_msgs/String"), st.none() | st.integers(0, 1000)),
        st.builds(Publish, st.just("/t"), st.just("a/B"), st.integers(0, 1000), st.booleans()),
        st.builds(ServiceRequest, st.integers(0, 2**31), st.just("/s"), st.binary(max_size=50)),
        st.builds(ServiceResponse, st.integers(0, 2**31), st.just("/s"), st.binary(max_size=50)),
        st.builds(TopicMessage, st.just("/t"), st.binary(max_size=50)),
        st.builds(Ping, st.text(max_size=30)),
        st.builds(Auth, st.text(max_size=30)),
    )
)
def test_what_a_client_sends_the_endpoint_receives_unchanged(event: Event) -> None:
    assert received(Conversation(Role.CLIENT).send(event)) == [event]


@settings(max_examples=100, deadline=None)
@given(
    event=st.one_of(
        st.builds(Error, st.text(max_size=30), st.none() | st.integers(0, 2**31)),
        st.builds(Warn, st.text(max_size=30)),
        st.builds(Log, st.text(max_size=30)),
        st.builds(PingResponse, st.text(max_size=30), st.none() | st.floats(0, 2e9)),
        st.builds(ServiceRequest, st.integers(0, 2**31), st.just("/s"), st.binary(max_size=50)),
        st.builds(ServiceResponse, st.integers(0, 2**31), st.just("/s"), st.binary(max_size=50)),
        st.builds(TopicMessage, st.just("/t"), st.binary(max_size=50)),
        st.lists(st.tuples(st.text(max_size=5), st.text(max_size=5)), max_size=3).map(
            lambda pairs: TopicList(tuple(name for name, _ in pairs), tuple(kind for _, kind in pairs))
        ),
    )
)
def test_what_the_endpoint_sends_the_client_receives_unchanged(event: Event) -> None:
    client = Conversation(Role.CLIENT)
    assert client.receive_data(protocol.handshake() + Conversation(Role.ENDPOINT).send(event))[1:] == [event]


def test_topic_list_query_accepts_an_empty_payload() -> None:
    assert parsed("__topic_list", b"") == TopicListQuery()


def test_client_commands_cover_the_table() -> None:
    assert protocol.CLIENT_COMMANDS == {
        "__subscribe",
        "__publish",
        "__ros_service",
        "__unity_service",
        "__request",
        "__response",
        "__topic_list",
        "__auth",
        "__ping",
        "__remove_subscriber",
        "__remove_publisher",
        "__remove_ros_service",
        "__remove_unity_service",
    }


def rejects(data: bytes, *fragments: str, role: Role = Role.ENDPOINT) -> RemoteProtocolError:
    (event,) = received(data, role)
    assert isinstance(event, InvalidInput), event
    message = str(event.error)
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"
    assert not event.error.fatal
    return event.error


def test_unknown_command_is_named() -> None:
    rejects(command("__frobnicate", {}), "unknown system command", "__frobnicate")
    rejects(command("__handshake", {"version": "v0.7.0"}), "unknown system command", "__handshake")
    rejects(command("__error", {"text": "a client cannot say this"}), "unknown system command", "__error")


def test_malformed_json_names_the_command() -> None:
    rejects(command("__subscribe", '{"topic": "/t",'), "__subscribe", "malformed JSON")


def test_non_utf8_payload_names_the_command() -> None:
    rejects(command("__subscribe", b"\xff{}"), "__subscribe", "UTF-8")


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
        ("__ping", {}, "request_time"),
        ("__remove_subscriber", {}, "topic"),
        ("__remove_unity_service", {}, "topic"),
    ],
)
def test_missing_field_is_named(destination: str, params: dict, field: str) -> None:
    rejects(command(destination, params), destination, "missing field", repr(field))


@pytest.mark.parametrize(
    ("destination", "params", "expected"),
    [
        (
            "__subscribe",
            {"topic": "/t", "message_name": "std_msgs/String", "priority": 1},
            Subscribe("/t", "std_msgs/String"),
        ),
        ("__topic_list", {"verbose": True}, TopicListQuery()),
        ("__remove_publisher", {"topic": "/t", "latch": False}, Remove("publisher", "/t")),
        ("__ping", {"request_time": "t", "sent_by": "Unity"}, Ping("t")),
    ],
)
def test_a_command_with_fields_we_do_not_know_is_carried_out_and_they_are_reported_once(
    destination: str, params: dict, expected: Event
) -> None:
    conversation = Conversation(Role.ENDPOINT)
    unknown = tuple(sorted(set(params) - {"topic", "message_name", "request_time"}))
    assert conversation.receive_data(command(destination, params)) == [IgnoredFields(destination, unknown), expected]
    assert conversation.receive_data(command(destination, params) * 2) == [expected, expected]


def test_unknown_fields_are_reported_per_command_and_field() -> None:
    conversation = Conversation(Role.ENDPOINT)
    first = {"topic": "/t", "message_name": "a/B", "x": 1}
    events = conversation.receive_data(
        command("__subscribe", first)
        + command("__subscribe", {**first, "y": 2})
        + command("__publish", first)
        + command("__request", {"srv_id": 5, "x": 1})
        + encode_frame("/srv", b"body")
    )
    assert events == [
        IgnoredFields("__subscribe", ("x",)),
        Subscribe("/t", "a/B"),
        IgnoredFields("__subscribe", ("y",)),
        Subscribe("/t", "a/B"),
        IgnoredFields("__publish", ("x",)),
        Publish("/t", "a/B"),
        IgnoredFields("__request", ("x",)),
        ServiceRequest(5, "/srv", b"body"),
    ]


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
        ("__subscribe", {"topic": "/t", "message_name": "std_msgs/String", "queue_size": 1.5}, "queue_size"),
        ("__subscribe", {"topic": 5, "message_name": "std_msgs/String"}, "topic"),
        ("__subscribe", {"topic": "/t", "message_name": ["std_msgs/String"]}, "message_name"),
        ("__auth", {"token": 1234}, "token"),
        ("__ping", {"request_time": 1234}, "request_time"),
    ],
)
def test_wrong_type_is_named(destination: str, params: dict, field: str) -> None:
    rejects(command(destination, params), destination, f"field {field!r} must be")


@pytest.mark.parametrize("destination", ["__publish", "__subscribe"])
def test_negative_queue_size_is_refused(destination: str) -> None:
    rejects(
        command(destination, {"topic": "/t", "message_name": "std_msgs/String", "queue_size": -1}),
        destination,
        "queue_size",
    )


@pytest.mark.parametrize(
    "topic",
    [
        "",
        "__hidden",
        "/with space",
        "/tab\there",
        "/nul\0",
        "/new\nline",
        "\x01x",
        "/esc\x1b",
        "/x\uffff",
        "/caf\u00e9",
        "//double",
        "/a-b",
        "1st",
    ],
)
@pytest.mark.parametrize("destination", ["__subscribe", "__publish", "__ros_service", "__unity_service"])
def test_bad_topic_is_named(destination: str, topic: str) -> None:
    rejects(command(destination, {"topic": topic, "message_name": "std_msgs/String"}), destination, "'topic'")


@pytest.mark.parametrize("character", ["\x01", "\x1b", "\uffff"])
def test_a_bad_character_in_a_name_is_shown_with_its_code_point(character: str) -> None:
    rejects(
        command("__subscribe", {"topic": f"/a{character}", "message_name": "std_msgs/String"}),
        f"U+{ord(character):04X}",
        "position 2",
    )


def test_a_registered_name_is_no_longer_than_a_destination_may_be() -> None:
    """One limit everywhere: a client can send frames to every topic it may register."""
    conversation = Conversation(Role.ENDPOINT, max_destination_bytes=32)
    longest = "/" + "a" * 31
    (accepted,) = conversation.receive_data(command("__publish", {"topic": longest, "message_name": "std_msgs/Empty"}))
    assert isinstance(accepted, Publish)
    (refused,) = conversation.receive_data(
        command("__publish", {"topic": longest + "a", "message_name": "std_msgs/Empty"})
    )
    assert isinstance(refused, InvalidInput) and "33 bytes long" in str(refused.error)


@pytest.mark.parametrize("topic", ["/t", "t", "~private", "/ns/sub_topic/x1", "/Robot_2/joint_states"])
def test_good_names_pass(topic: str) -> None:
    event = parsed("__subscribe", {"topic": topic, "message_name": "std_msgs/String"})
    assert isinstance(event, Subscribe) and event.topic == topic


def test_deeply_nested_json_is_refused_as_bad_input() -> None:
    rejects(protocol.encode_frame("__subscribe", b"[" * 100_000 + b"]" * 100_000), "__subscribe", "nested")


def nested(depth: int, inner: str = "1") -> str:
    """A JSON value whose arrays and objects alternate depth levels deep, with siblings on the way."""
    value = inner
    for level in range(depth):
        sibling = "[]" if level else "0"  # no deeper than the chain
        value = f'{{"k": {value}, "s": [0]}}' if level % 2 else f"[0, {value}, {sibling}]"
    return value


@pytest.mark.parametrize("depth", [MAX_JSON_NESTING - 1, MAX_JSON_NESTING])
def test_json_nested_to_the_limit_is_parsed(depth: int) -> None:
    events = received(
        command("__subscribe", f'{{"topic": "/t", "message_name": "std_msgs/String", "x": {nested(depth - 1)}}}')
    )
    assert [type(event) for event in events] == [IgnoredFields, Subscribe]


@pytest.mark.parametrize(
    "payload",
    [
        f'{{"topic": "/t", "message_name": "std_msgs/String", "x": {nested(MAX_JSON_NESTING)}}}',
        '{"x": ' + "[" * 10_000,  # never closed: the decoder would descend before it finds the error
        '{"x": ' + "[[1], " * 40 + "]" * 40 + "}",  # no run of opening brackets, still 41 deep
    ],
    ids=["one-level-too-deep", "unclosed", "climbing"],
)
def test_json_nested_past_the_limit_is_refused_before_decoding(payload: str) -> None:
    rejects(command("__subscribe", payload), "__subscribe", f"nested more than {MAX_JSON_NESTING} levels")


def test_brackets_inside_strings_do_not_count_as_nesting() -> None:
    escaped_quotes = '\\"' + "[" * 100 + '\\"'
    events = received(
        command("__subscribe", f'{{"topic": "/t", "message_name": "std_msgs/String", "x": "{escaped_quotes}"}}')
    )
    assert [type(event) for event in events] == [IgnoredFields, Subscribe]
    (refused,) = received(command("__subscribe", {"topic": "[" * 100, "message_name": "std_msgs/String"}))
    assert isinstance(refused, InvalidInput) and "nested" not in str(refused.error)


def test_deep_json_cannot_abort_the_process_after_a_caught_recursion_error() -> None:
    """Python 3.8 aborts ("Cannot recover from stack overflow") if its JSON decoder recurses past the recursion
    limit while a RecursionError caught earlier on the same stack still counts, as when a garbage collector's
    finalizer hit it deep inside the decoder: the endpoint's reader must never get there."""
    script = textwrap.dedent(
        """
        import sys
        from bridge.protocol import Conversation, Role, encode_frame

        def recurse():
            recurse()

        def at_depth(frames):
            if frames:
                return at_depth(frames - 1)
            try:
                recurse()
            except RecursionError:
                pass
            frame = encode_frame("__subscribe", b"[" * 100_000 + b"]" * 100_000)
            print(type(Conversation(Role.ENDPOINT).receive_data(frame)[0]).__name__)

        at_depth(sys.getrecursionlimit() - 30)
        """
    )
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert (result.returncode, result.stdout.strip()) == (0, "InvalidInput"), result.stderr[-2000:]


def test_bad_topic_in_remove_is_named() -> None:
    rejects(command("__remove_subscriber", {"topic": ""}), "__remove_subscriber", "'topic'")


@pytest.mark.parametrize(
    "message_name",
    [
        "String",
        "std_msgs/",
        "/String",
        "std_msgs/msg/String",
        "std msgs/String",
        "std_msgs/Str-ing",
        "",
        "a/b/c",
        "1pkg/Type",
        "pkg/_Type",
        "caf\u00e9/Type",
        "std_msgs/String\x00",
    ],
)
def test_bad_message_name_is_named(message_name: str) -> None:
    rejects(command("__subscribe", {"topic": "/t", "message_name": message_name}), "__subscribe", "'message_name'")


@pytest.mark.parametrize("message_name", ["std_msgs/String", "sensor_msgs/JointState", "tf2_msgs/TFMessage"])
def test_good_message_names_pass(message_name: str) -> None:
    event = parsed("__subscribe", {"topic": "/t", "message_name": message_name})
    assert isinstance(event, Subscribe) and event.message_name == message_name


def test_keepalives_are_not_events() -> None:
    assert received(protocol.KEEPALIVE_FRAME * 3) == []


# --- the conversation: service headers and their bodies ---------------------------------------------------------


def test_a_service_header_and_its_body_are_one_event_whatever_the_body_is_called() -> None:
    header = command("__request", {"srv_id": 7})
    conversation = Conversation(Role.ENDPOINT)
    assert conversation.receive_data(header) == []
    assert conversation.pending_service == (ServiceRequest, 7)
    # The very next frame is the body, even one that looks like a command; a keepalive between them is skipped.
    assert conversation.receive_data(protocol.KEEPALIVE_FRAME + encode_frame("__subscribe", b"body")) == [
        ServiceRequest(7, "__subscribe", b"body")
    ]
    assert conversation.pending_service is None
    assert conversation.receive_data(encode_frame("/t", b"x")) == [TopicMessage("/t", b"x")]


@settings(max_examples=200, deadline=None)
@given(
    events=st.lists(
        st.one_of(
            st.builds(TopicMessage, st.sampled_from(["/a", "/b", "c"]), st.binary(max_size=20)),
            st.builds(ServiceRequest, st.integers(0, 10**6), st.sampled_from(["/s", "__x"]), st.binary(max_size=20)),
            st.builds(ServiceResponse, st.integers(0, 10**6), st.just("/s"), st.binary(max_size=20)),
            st.builds(Subscribe, st.just("/t"), st.just("std_msgs/String")),
            st.just(Keepalive()),
        ),
        min_size=1,
        max_size=15,
    ),
    data=st.data(),
)
def test_any_split_of_a_conversation_gives_the_same_events(events: list, data) -> None:
    client = Conversation(Role.CLIENT)
    stream = b"".join(client.send(event) for event in events)
    cuts = sorted(set(data.draw(st.lists(st.integers(0, len(stream)), max_size=20))))
    endpoint = Conversation(Role.ENDPOINT)
    got = []
    for start, end in zip([0, *cuts], [*cuts, len(stream)]):
        got += endpoint.receive_data(stream[start:end])
    assert got == [event for event in events if not isinstance(event, Keepalive)]
    assert endpoint.frames_received == sum(2 if isinstance(e, (ServiceRequest, ServiceResponse)) else 1 for e in events)


def test_a_body_whose_name_is_not_utf8_fails_that_call_by_its_srv_id() -> None:
    data = command("__response", {"srv_id": 1001}) + raw_frame(b"/s\xff", b"body") + encode_frame("/t", b"x")
    invalid, message = received(data)
    assert isinstance(invalid, InvalidInput) and invalid.error.srv_id == 1001 and "UTF-8" in str(invalid.error)
    assert message == TopicMessage("/t", b"x")


def test_a_bad_service_header_expects_no_body() -> None:
    invalid, message = received(command("__request", {"srv_id": "7"}) + encode_frame("/t", b"x"))
    assert isinstance(invalid, InvalidInput) and "srv_id" in str(invalid.error)
    assert message == TopicMessage("/t", b"x")


def test_a_bad_frame_costs_only_itself() -> None:
    data = encode_frame("/a", b"1") + raw_frame(b"/bad\xfe", b"") + command("__nope", {}) + encode_frame("/b", b"2")
    first, bad_name, unknown, last = received(data)
    assert (first, last) == (TopicMessage("/a", b"1"), TopicMessage("/b", b"2"))
    assert isinstance(bad_name, InvalidInput) and "UTF-8" in str(bad_name.error)
    assert isinstance(unknown, InvalidInput) and "__nope" in str(unknown.error)


def test_framing_loss_comes_after_the_frames_before_it_and_ends_the_conversation() -> None:
    conversation = Conversation(Role.ENDPOINT, max_payload_bytes=4)
    before, lost = conversation.receive_data(encode_frame("/a", b"1") + encode_frame("/b", b"12345"))
    assert before == TopicMessage("/a", b"1")
    assert isinstance(lost, InvalidInput) and lost.error.fatal and "limit" in str(lost.error)
    with pytest.raises(RemoteProtocolError):
        conversation.receive_data(encode_frame("/a", b"1"))


# --- the conversation, client role: what an endpoint says -------------------------------------------------------


def test_a_client_expects_the_handshake_first_and_reads_its_metadata() -> None:
    client = Conversation(Role.CLIENT)
    assert client.awaiting_handshake
    (refused,) = client.receive_data(encode_frame("/t", b"x"))
    assert isinstance(refused, InvalidInput) and "__handshake" in str(refused.error)
    (handshake,) = client.receive_data(protocol.handshake())
    assert handshake == Handshake("v0.7.0", {"protocol": "ROS1"}) and handshake.is_compatible
    assert not client.awaiting_handshake
    assert client.receive_data(encode_frame("/t", b"x")) == [TopicMessage("/t", b"x")]


def test_an_incompatible_handshake_is_reported_as_such() -> None:
    (handshake,) = Conversation(Role.CLIENT).receive_data(encode(Handshake("v0.6.0", {"protocol": "ROS2"})))
    assert isinstance(handshake, Handshake) and not handshake.is_compatible
    (bad,) = Conversation(Role.CLIENT).receive_data(command("__handshake", {"version": "v0.7.0", "metadata": "{"}))
    assert isinstance(bad, InvalidInput) and "metadata" in str(bad.error)
    deep = "[" * 100_000 + "]" * 100_000
    (bad,) = Conversation(Role.CLIENT).receive_data(command("__handshake", {"version": "v0.7.0", "metadata": deep}))
    assert isinstance(bad, InvalidInput) and "metadata" in str(bad.error)


def test_an_error_names_the_call_it_fails() -> None:
    client = Conversation(Role.CLIENT)
    events = client.receive_data(
        protocol.handshake() + command("__error", {"text": "no", "srv_id": 101}) + command("__error", {"text": "plain"})
    )
    assert events[1:] == [Error("no", 101), Error("plain")]


def test_a_client_refuses_what_only_clients_say() -> None:
    client = Conversation(Role.CLIENT)
    client.receive_data(protocol.handshake())
    (event,) = client.receive_data(command("__subscribe", {"topic": "/t", "message_name": "a/B"}))
    assert isinstance(event, InvalidInput) and "unknown system command" in str(event.error)


def test_a_topic_list_must_pair_names_and_types() -> None:
    client = Conversation(Role.CLIENT)
    client.receive_data(protocol.handshake())
    (event,) = client.receive_data(command("__topic_list", {"topics": ["/a"], "types": []}))
    assert isinstance(event, InvalidInput) and "same length" in str(event.error)


# --- the conversation: what we may send ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("role", "event"),
    [
        (Role.CLIENT, Error("only endpoints report errors")),
        (Role.CLIENT, TopicList((), ())),
        (Role.CLIENT, Handshake("v0.7.0", {})),
        (Role.ENDPOINT, Subscribe("/t", "std_msgs/String")),
        (Role.ENDPOINT, Ping("t")),
        (Role.ENDPOINT, Keepalive()),
    ],
)
def test_each_role_sends_only_its_own_events(role: Role, event: Event) -> None:
    with pytest.raises(LocalProtocolError, match=type(event).__name__):
        Conversation(role).send(event)


@pytest.mark.parametrize(
    "event",
    [
        Subscribe("", "std_msgs/String"),
        Publish("/t", "String"),
        Publish("/t", "a/B", -1),
        Remove("publisher", "a b"),
        TopicMessage("__t", b""),
        TopicMessage("", b""),
    ],
)
def test_we_never_send_what_we_would_refuse(event: Event) -> None:
    with pytest.raises(LocalProtocolError):
        Conversation(Role.CLIENT).send(event)
