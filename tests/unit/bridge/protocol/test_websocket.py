"""bridge.protocol.websocket without I/O: two links (endpoint and client) handing bytes to each other."""

from __future__ import annotations

import struct
import threading

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from wsproto.events import BytesMessage, CloseConnection, Ping, TextMessage

from bridge import protocol
from bridge.protocol import (
    Conversation,
    Handshake,
    InvalidInput,
    Keepalive,
    Role,
    ServiceResponse,
    Subscribe,
    TopicMessage,
)
from bridge.protocol.websocket import UpgradeRequest, WebSocketLink, refusal_response, split_frames


def upgraded_pair(max_payload_bytes: int = protocol.DEFAULT_MAX_PAYLOAD_BYTES) -> tuple[WebSocketLink, WebSocketLink]:
    endpoint = WebSocketLink(
        Role.ENDPOINT, Conversation(Role.ENDPOINT, max_payload_bytes=max_payload_bytes), protocol.handshake()
    )
    client = WebSocketLink(Role.CLIENT, Conversation(Role.CLIENT))
    assert endpoint.receive_data(client.upgrade_request("localhost:9090", "/")) == []
    endpoint.accept()
    assert client.receive_data(endpoint.data_to_send()) == [Handshake("v0.7.0", {"protocol": "ROS1"})]
    return endpoint, client


def client_bytes(client: WebSocketLink, *events) -> bytes:
    conversation = Conversation(Role.CLIENT)
    return client.wrap(b"".join(conversation.send(event) for event in events))


def test_the_upgrade_is_answered_and_the_handshake_follows_it() -> None:
    endpoint = WebSocketLink(Role.ENDPOINT, Conversation(Role.ENDPOINT), protocol.handshake())
    client = WebSocketLink(Role.CLIENT, Conversation(Role.CLIENT))
    assert endpoint.buffered_bytes >= 1  # the upgrade request is under way: the frame deadline runs
    request = client.upgrade_request("localhost:9090", "/ros")
    assert endpoint.receive_data(request[:10]) == [] and not endpoint.upgraded
    assert endpoint.receive_data(request[10:]) == [] and not endpoint.upgraded  # until the endpoint decides
    assert endpoint.pending_request == UpgradeRequest("/ros", None, None) and endpoint.data_to_send() == b""
    endpoint.accept()
    assert endpoint.upgraded and endpoint.buffered_bytes == 0
    answer = endpoint.data_to_send()
    assert answer.startswith(b"HTTP/1.1 101 ") and endpoint.data_to_send() == b""
    assert client.receive_data(answer) == [Handshake("v0.7.0", {"protocol": "ROS1"})] and client.upgraded


def request_with(*headers: tuple[str, str]) -> bytes:
    lines = [
        "GET /ros HTTP/1.1",
        "Host: localhost:9090",
        "Upgrade: websocket",
        "Connection: Upgrade",
        "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==",
        "Sec-WebSocket-Version: 13",
        *(f"{name}: {value}" for name, value in headers),
    ]
    return ("\r\n".join(lines) + "\r\n\r\n").encode()


def test_the_request_says_the_pages_origin_the_forwarded_addresses_and_the_proxys_secret() -> None:
    endpoint = WebSocketLink(Role.ENDPOINT, Conversation(Role.ENDPOINT), protocol.handshake())
    request = request_with(
        ("Origin", "https://Lab.Example"),
        ("X-Forwarded-For", "10.0.0.9"),
        ("x-forwarded-for", "192.168.1.7"),
        ("X-Proxy-Secret", "s3cret"),
    )
    assert endpoint.receive_data(request) == []
    assert endpoint.pending_request == UpgradeRequest("/ros", "https://Lab.Example", "10.0.0.9, 192.168.1.7", "s3cret")


def test_a_refused_request_gets_its_http_answer_and_nothing_more() -> None:
    endpoint = WebSocketLink(Role.ENDPOINT, Conversation(Role.ENDPOINT), protocol.handshake())
    endpoint.receive_data(request_with(("Origin", "https://attacker.example")))
    endpoint.refuse("403 Forbidden", "the origin https://attacker.example may not open a WebSocket here")
    answer = endpoint.data_to_send()
    assert answer.startswith(b"HTTP/1.1 403 Forbidden\r\n") and answer.endswith(b"here\n")
    assert endpoint.closed is not None and "403" in endpoint.closed and not endpoint.upgraded
    assert endpoint.receive_data(b"more") == [] and endpoint.close() == b"" and endpoint.data_to_send() == b""


def test_only_the_newest_ping_of_a_read_is_answered_and_pongs_can_be_dropped() -> None:
    endpoint, client = upgraded_pair()
    endpoint.receive_data(b"".join(client._send(Ping(b"%d" % n)) for n in range(3)))
    assert endpoint.pongs_waiting() > 0 and endpoint.pongs_dropped == 2
    pongs = [event for event in _client_events(client, endpoint.data_to_send())]
    assert [bytes(event.payload) for event in pongs] == [b"2"]
    endpoint.receive_data(client._send(Ping(b"unread")))
    assert endpoint.data_to_send(pongs=False) == b"" and endpoint.pongs_dropped == 3 and endpoint.pongs_waiting() == 0


def test_nothing_follows_the_close() -> None:
    endpoint, client = upgraded_pair()
    endpoint.receive_data(client._send(Ping(b"before")))
    close = endpoint.close("bye")
    assert endpoint.close_sent and endpoint.data_to_send() == b""  # the pong not yet taken is not sent after it
    assert endpoint.receive_data(client._send(Ping(b"after"))) == [] and endpoint.data_to_send() == b""
    assert closing(client, close)[0] == 1008


def test_closing_waits_for_a_read_inside_wsproto() -> None:
    """close() on another thread while the reader is inside wsproto: it waits for the read to end (one lock)."""
    endpoint, client = upgraded_pair()
    inside, release = threading.Event(), threading.Event()
    receive = endpoint._ws.receive_data

    def slow_receive(data: bytes) -> None:
        inside.set()
        release.wait(5)
        receive(data)

    endpoint._ws.receive_data = slow_receive  # type: ignore[method-assign]
    reader = threading.Thread(target=endpoint.receive_data, args=(client._send(Ping(b"x")),))
    reader.start()
    assert inside.wait(5)
    closed: list[bytes] = []
    closer = threading.Thread(target=lambda: closed.append(endpoint.close("going")))
    closer.start()
    closer.join(0.2)
    assert closer.is_alive() and not closed  # waiting for the read
    release.set()
    reader.join(5)
    closer.join(5)
    assert closed and closing(client, closed[0])[0] == 1008


def _client_events(client: WebSocketLink, data: bytes) -> list:
    client._ws.receive_data(data)
    return [event for event in client._ws.events() if not isinstance(event, CloseConnection)]


def test_each_frame_goes_in_a_message_of_its_own() -> None:
    endpoint, client = upgraded_pair()
    pair = protocol.encode(ServiceResponse(7, "/srv", b"x" * 70_000))  # header and body, sent as one item
    wrapped = endpoint.wrap(pair)
    assert client.receive_data(wrapped) == [ServiceResponse(7, "/srv", b"x" * 70_000)]
    # two binary messages: a 7-bit length for the small header, a 64-bit one for the body
    header_frame_length = len(pair) - len(protocol.encode_frame("/srv", b"x" * 70_000))
    assert wrapped[:2] == bytes((0x82, header_frame_length))
    body_at = 2 + header_frame_length
    assert wrapped[body_at : body_at + 2] == bytes((0x82, 127))
    assert struct.unpack("!Q", wrapped[body_at + 2 : body_at + 10])[0] == len(wrapped) - body_at - 10
    middle = endpoint.wrap(protocol.encode_frame("/t", b"y" * 300))  # a 16-bit length
    assert middle[:2] == bytes((0x82, 126)) and client.receive_data(middle) == [TopicMessage("/t", b"y" * 300)]


def test_a_single_frame_is_not_copied_to_be_split() -> None:
    frame = protocol.encode_frame("/t", b"abc")
    assert split_frames(frame)[0] is frame
    two = frame + protocol.encode_frame("/u", b"")
    assert [bytes(part) for part in split_frames(two)] == [frame, protocol.encode_frame("/u", b"")]


def test_whole_frames_may_share_a_message_or_span_its_fragments() -> None:
    endpoint, client = upgraded_pair()
    frames = Conversation(Role.CLIENT).send(Subscribe("/a", "std_msgs/String")) + protocol.encode_frame("/a", b"hi")
    assert endpoint.receive_data(client.message(frames)) == [
        Subscribe("/a", "std_msgs/String"),
        TopicMessage("/a", b"hi"),
    ]
    frame = protocol.encode_frame("/a", b"z" * 1000)
    fragments = client._send(BytesMessage(data=frame[:333], message_finished=False)) + client._send(
        BytesMessage(data=frame[333:], message_finished=True)
    )
    assert endpoint.receive_data(fragments) == [TopicMessage("/a", b"z" * 1000)]


def test_a_message_that_ends_inside_a_frame_ends_the_connection() -> None:
    endpoint, client = upgraded_pair()
    frame = protocol.encode_frame("/a", b"abcdef")
    events = endpoint.receive_data(client.message(frame[:-2]))
    assert len(events) == 1 and isinstance(events[0], InvalidInput) and events[0].error.fatal
    assert "ended inside a ROS-TCP frame" in str(events[0].error) and endpoint.closed is not None
    assert endpoint.receive_data(client.message(frame)) == []  # nothing more is read
    assert closing(client, endpoint.close()) == (1008, str(events[0].error)[:123])
    assert endpoint.close() == b""  # said once


def test_an_oversized_frame_ends_the_connection_before_its_payload_comes() -> None:
    endpoint, client = upgraded_pair(max_payload_bytes=1000)
    header = protocol.encode_frame("/a", b"")[:-4] + struct.pack("<I", 10**6)
    events = endpoint.receive_data(client._send(BytesMessage(data=header, message_finished=False)))
    assert len(events) == 1 and events[0].error.fatal and "1000" in str(events[0].error)
    assert closing(client, endpoint.close())[0] == 1008


def test_a_text_message_is_refused_and_the_next_frames_are_read() -> None:
    endpoint, client = upgraded_pair()
    text = client._send(TextMessage(data='{"op": "advertise"}'))
    events = endpoint.receive_data(text + client_bytes(client, Keepalive(), Subscribe("/a", "std_msgs/String")))
    assert isinstance(events[0], InvalidInput) and not events[0].error.fatal and "binary" in str(events[0].error)
    assert events[1:] == [Subscribe("/a", "std_msgs/String")] and endpoint.closed is None


def test_a_ping_is_answered() -> None:
    endpoint, client = upgraded_pair()
    assert endpoint.receive_data(client._send(Ping(b"are you there"))) == []
    client.receive_data(endpoint.data_to_send())  # wsproto reads the pong without complaint
    assert endpoint.closed is None and client.closed is None


@pytest.mark.parametrize("mid_frame", [False, True])
def test_the_peers_close_is_answered_and_said(mid_frame: bool) -> None:
    endpoint, client = upgraded_pair()
    if mid_frame:
        endpoint.receive_data(client._send(BytesMessage(data=b"\x02\x00\x00\x00/a", message_finished=False)))
    assert endpoint.receive_data(client.close()) == []
    assert endpoint.closed == "WebSocket closed by the peer (code 1000)" + (
        ", in the middle of a frame" if mid_frame else ""
    )
    assert closing(client, endpoint.data_to_send())[0] == 1000
    assert endpoint.close() == b""


@pytest.mark.parametrize("first", ["client", "endpoint"])
def test_the_answer_to_ones_own_close_ends_the_link_quietly(first: str) -> None:
    endpoint, client = upgraded_pair()
    closer, peer = (client, endpoint) if first == "client" else (endpoint, client)
    assert peer.receive_data(closer.close(going_away=True)) == []
    assert closer.receive_data(peer.data_to_send()) == []  # its answer: no error
    assert closer.closed == "WebSocket closed (code 1001), the peer answering this end's close"


def test_an_unmasked_frame_is_broken_framing() -> None:
    endpoint, _ = upgraded_pair()
    frame = protocol.encode_frame("/a", b"abc")
    events = endpoint.receive_data(bytes((0x82, len(frame))) + frame)
    assert len(events) == 1 and events[0].error.fatal and "broken WebSocket framing" in str(events[0].error)
    assert closing(WebSocketLink(Role.CLIENT, Conversation(Role.CLIENT)), endpoint.close(), upgraded=False)[0] == 1002


def test_a_request_that_is_not_an_upgrade_gets_an_http_error() -> None:
    endpoint = WebSocketLink(Role.ENDPOINT, Conversation(Role.ENDPOINT), protocol.handshake())
    events = endpoint.receive_data(b"GET / HTTP/1.1\r\nHost: x\r\n\r\n")
    assert len(events) == 1 and events[0].error.fatal and "upgrade failed" in str(events[0].error)
    assert endpoint.data_to_send().startswith(b"HTTP/1.1 4")
    assert endpoint.close() == b""  # the request had its answer


@pytest.mark.parametrize("going_away, status", [(False, b"408"), (True, b"503")])
def test_closing_before_the_upgrade_answers_in_http(going_away: bool, status: bytes) -> None:
    endpoint = WebSocketLink(Role.ENDPOINT, Conversation(Role.ENDPOINT), protocol.handshake())
    answer = endpoint.close("no upgrade request within 30 s", going_away=going_away)
    assert answer.startswith(b"HTTP/1.1 " + status) and answer.endswith(b"no upgrade request within 30 s\n")
    assert endpoint.close("again") == b""


def test_a_refusal_tells_the_client_why() -> None:
    client = WebSocketLink(Role.CLIENT, Conversation(Role.CLIENT))
    client.upgrade_request("localhost:9090")
    assert client.receive_data(refusal_response("connection refused: the endpoint is full")) == []
    assert client.closed == "the WebSocket upgrade was refused with HTTP 503: connection refused: the endpoint is full"


def closing(client: WebSocketLink, data: bytes, upgraded: bool = True) -> tuple[int, str]:
    """The code and reason of the close in `data`, as a client reads them."""
    import wsproto

    reader = client._ws if upgraded else wsproto.Connection(wsproto.ConnectionType.CLIENT)
    reader.receive_data(data)
    closes = [event for event in reader.events() if isinstance(event, CloseConnection)]
    assert len(closes) == 1, closes
    return int(closes[0].code), closes[0].reason


# Frames a client may send, as (destination, payload); JSON commands are kept valid so the events are comparable.
frames = st.lists(
    st.one_of(
        st.tuples(st.sampled_from(["/a", "/b/c"]), st.binary(max_size=300)),
        st.just(("__subscribe", b'{"topic": "/a", "message_name": "std_msgs/String"}')),
        st.just(("", b"")),
    ),
    max_size=12,
)


@settings(max_examples=150, deadline=None)
@given(frames=frames, per_message=st.integers(1, 4), chunk=st.integers(1, 700))
def test_over_websocket_the_events_are_those_of_tcp(frames, per_message: int, chunk: int) -> None:
    """Whatever the grouping of whole frames into messages, and the chunks the stream arrives in."""
    encoded = [protocol.encode_frame(destination, payload) for destination, payload in frames]
    over_tcp = Conversation(Role.ENDPOINT).receive_data(b"".join(encoded))
    endpoint, client = upgraded_pair()
    stream = b"".join(
        client.message(b"".join(encoded[start : start + per_message])) for start in range(0, len(encoded), per_message)
    )
    over_websocket = []
    for start in range(0, len(stream), chunk):
        over_websocket.extend(endpoint.receive_data(stream[start : start + chunk]))
    assert over_websocket == over_tcp and endpoint.closed is None
