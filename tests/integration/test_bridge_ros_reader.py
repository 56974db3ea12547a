"""bridge.ros.reader.read_raw_messages, the endpoint's read of TCPROS messages from ROS publishers, on real sockets:
every message comes out whole and in order however the stream was split between rospy's read buffer and the socket,
and a publisher that goes mid-message ends the connection as rospy's own reads do."""

from __future__ import annotations

import io
import socket
import struct
import threading

import pytest
import rospy.impl.tcpros_pubsub
from rospy.exceptions import TransportTerminated

from bridge.protocol.framing import LARGE_PAYLOAD_BYTES
from bridge.ros import reader as ros_reader
from bridge.ros.raw_types import RawMessage
from bridge.ros.reader import FLOOD_READ_BYTES, SUBSCRIBER_READ_BYTES, next_read_size, read_raw_messages

pytestmark = pytest.mark.lane("endpoint", on=("noetic",))

SIZES = [0, 1, 321, LARGE_PAYLOAD_BYTES - 1, LARGE_PAYLOAD_BYTES, 5, 2_764_800, 17, 1 << 20]


def payloads() -> list[bytes]:
    return [
        bytes((index * 7 + offset) % 251 for offset in range(min(size, 251))) * (size // 251 + 1)
        for index, size in enumerate(SIZES)
    ]


def tcpros(messages: list[bytes]) -> bytes:
    return b"".join(struct.pack("<I", len(message)) + message for message in messages)


def read_all(stream: bytes, in_buffer: int, read_bytes: int = 64 * 1024) -> list[bytes]:
    """Deliver `stream` as rospy's receive_once would: the first `in_buffer` bytes already in its read buffer, the
    rest on the socket, read in `read_bytes` pieces whenever read_raw_messages finds no complete message."""
    sender, receiver = socket.socketpair()
    writer = threading.Thread(target=sender.sendall, args=(stream[in_buffer:],), daemon=True)
    writer.start()
    buffer = io.BytesIO()
    buffer.write(stream[:in_buffer])
    received: list[RawMessage] = []
    try:
        while len(received) < len(SIZES):
            if buffer.tell() >= 4:
                read_raw_messages(buffer, received, receiver, RawMessage)
            if len(received) < len(SIZES):
                buffer.write(receiver.recv(read_bytes))
    finally:
        writer.join(timeout=10)
        sender.close()
        receiver.close()
    assert buffer.tell() == 0  # nothing left over
    return [bytes(message._buff) for message in received]


@pytest.mark.parametrize("in_buffer", [0, 3, 4, 100, LARGE_PAYLOAD_BYTES + 9, LARGE_PAYLOAD_BYTES * 2 + 20, 3_000_000])
def test_every_message_comes_out_whole_and_in_order_however_the_stream_is_split(in_buffer: int) -> None:
    messages = payloads()
    assert read_all(tcpros(messages), in_buffer) == messages


@pytest.mark.parametrize("read_bytes", [1, 4096, 1 << 20])
def test_any_read_size_gives_the_same_messages(read_bytes: int) -> None:
    messages = payloads()
    assert read_all(tcpros(messages), 0, read_bytes) == messages


def test_a_publisher_gone_in_the_middle_of_a_large_message_ends_the_connection() -> None:
    message = bytes(LARGE_PAYLOAD_BYTES * 4)
    stream = tcpros([message])
    sender, receiver = socket.socketpair()
    buffer = io.BytesIO()
    buffer.write(stream[:1000])
    sender.sendall(stream[1000 : len(stream) // 2])
    sender.close()
    try:
        with pytest.raises(TransportTerminated):
            read_raw_messages(buffer, [], receiver, RawMessage)
    finally:
        receiver.close()


def test_a_large_message_begun_in_the_buffer_is_read_whole_from_the_socket_in_one_call() -> None:
    message = bytes(range(256)) * 4096  # 1 MiB
    stream = tcpros([message, b"next"])
    sender, receiver = socket.socketpair()
    writer = threading.Thread(target=sender.sendall, args=(stream[100:],), daemon=True)
    writer.start()
    buffer = io.BytesIO()
    buffer.write(stream[:100])
    received: list[RawMessage] = []
    try:
        assert read_raw_messages(buffer, received, receiver, RawMessage)  # says it read from the socket
        assert [bytes(m._buff) for m in received] == [message]
        assert isinstance(received[0]._buff, bytearray)  # delivered in the buffer it was read into
        assert buffer.tell() == 0  # the next message is still on the socket, untouched
        assert receiver.recv(8) == stream[-8:]
    finally:
        writer.join(timeout=10)
        sender.close()
        receiver.close()


def test_small_messages_in_the_buffer_are_not_read_from_the_socket() -> None:
    sender, receiver = socket.socketpair()
    buffer = io.BytesIO()
    buffer.write(tcpros([b"a" * 100, b"b" * 200]) + b"\x10\x00")  # two messages and the start of a third
    received: list[RawMessage] = []
    try:
        assert not read_raw_messages(buffer, received, receiver, RawMessage)
        assert [bytes(m._buff) for m in received] == [b"a" * 100, b"b" * 200]
        assert buffer.getvalue() == b"\x10\x00"
    finally:
        sender.close()
        receiver.close()


def test_the_read_size_grows_for_a_flood_and_shrinks_for_large_messages() -> None:
    assert next_read_size(SUBSCRIBER_READ_BYTES, 100, read_large=False) == SUBSCRIBER_READ_BYTES  # light traffic
    assert next_read_size(SUBSCRIBER_READ_BYTES, SUBSCRIBER_READ_BYTES + 7, read_large=False) == FLOOD_READ_BYTES
    assert next_read_size(FLOOD_READ_BYTES, 100, read_large=False) == FLOOD_READ_BYTES  # a lull changes nothing
    assert next_read_size(FLOOD_READ_BYTES, FLOOD_READ_BYTES, read_large=True) == SUBSCRIBER_READ_BYTES


def test_rospy_subscriber_connections_of_raw_classes_read_with_a_size_that_follows_the_traffic() -> None:
    ros_reader.install_raw_reader()
    protocol = rospy.impl.tcpros_pubsub.TCPROSSub(
        "/flood", RawMessage, queue_size=None, buff_size=SUBSCRIBER_READ_BYTES
    )
    small = [bytes(200)] * (SUBSCRIBER_READ_BYTES // 200)  # a full read of a flood
    large = bytes(LARGE_PAYLOAD_BYTES * 2)
    sender, receiver = socket.socketpair()
    try:
        buffer = io.BytesIO()
        buffer.write(tcpros(small))
        received: list[RawMessage] = []
        protocol.read_messages(buffer, received, receiver)
        assert len(received) == len(small) and protocol.buff_size == FLOOD_READ_BYTES
        stream = tcpros([large])
        buffer.write(stream[:1000])
        writer = threading.Thread(target=sender.sendall, args=(stream[1000:],), daemon=True)
        writer.start()
        protocol.read_messages(buffer, received, receiver)
        assert bytes(received[-1]._buff) == large and protocol.buff_size == SUBSCRIBER_READ_BYTES
        writer.join(timeout=10)
    finally:
        sender.close()
        receiver.close()
