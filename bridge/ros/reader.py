"""How the endpoint's rospy subscribers read: every complete TCPROS message out of rospy's buffer as raw bytes, a
large one straight from the socket into the buffer it is delivered in, with a read size that follows the traffic.
Installed once in rospy's subscriber protocol (install_raw_reader); every class but the raw ones keeps rospy's way.
"""

from __future__ import annotations

import io
import socket
import struct
from typing import Any

import rospy
import rospy.impl.tcpros_pubsub
from rospy.exceptions import TransportTerminated

from bridge.protocol.framing import LARGE_PAYLOAD_BYTES
from bridge.ros.raw_types import RawMessage

_U32 = struct.Struct("<I")

__all__ = [
    "SUBSCRIBER_READ_BYTES",
    "FLOOD_READ_BYTES",
    "DIRECT_RECEIVE_MAX_BYTES",
    "read_raw_messages",
    "next_read_size",
    "install_raw_reader",
]

# rospy's read size for the endpoint's subscribers follows the traffic (next_read_size): its default to begin with and
# while large messages come, so little of one goes through rospy's read buffer (see read_raw_messages); larger once a
# read finds more waiting than it takes, a flood of small messages (measured: with 64 KiB reads, a JointState flood
# reached a client at 0.8 of the rate it did with 1 MiB reads).
SUBSCRIBER_READ_BYTES = 64 * 1024
FLOOD_READ_BYTES = 1024 * 1024
# A message from LARGE_PAYLOAD_BYTES up to this size is read straight into the buffer it is delivered in; a larger
# one (more than a client may be sent by default) takes rospy's way, which grows its buffer only as bytes come.
DIRECT_RECEIVE_MAX_BYTES = 64 * 1024 * 1024


def read_raw_messages(
    buffer: io.BytesIO, messages: list[RawMessage], sock: socket.socket, raw: type[RawMessage]
) -> bool:
    """What rospy's deserialize_messages does with its read buffer (every complete TCPROS message out of `buffer`
    into `messages`, the rest kept), for raw classes and with less copying: a large message whose first bytes are
    in the buffer is read from `sock` straight into a buffer of its size, which is what is delivered (a bytearray).
    rospy's way copies each message three times or more on the way (its read buffer grows by reallocation, the
    message is cut out of it, the buffer is shrunk again): for a 2.7 MB camera image, that was most of the
    endpoint's work. Returns whether a message was read straight from the socket. Raises TransportTerminated when
    the publisher goes, as rospy's reads do."""
    end = buffer.tell()
    position = 0
    read_large = False
    with buffer.getbuffer() as view:
        while end - position >= 4:
            (size,) = _U32.unpack_from(view, position)
            start, stop = position + 4, position + 4 + size
            if stop <= end:
                messages.append(raw(bytes(view[start:stop])))
                position = stop
                continue
            if LARGE_PAYLOAD_BYTES <= size <= DIRECT_RECEIVE_MAX_BYTES:
                payload = bytearray(size)
                payload[: end - start] = view[start:end]
                _receive_into(sock, memoryview(payload)[end - start :])
                messages.append(raw(payload))  # type: ignore[arg-type]  # bytes-like: framed and compared only
                position = end
                read_large = True
            break
        if not position:  # nothing taken (a message still coming): the buffer stays as it is, as rospy leaves it
            return read_large
        rest = bytes(view[position:end])
    buffer.seek(0)
    buffer.truncate()
    buffer.write(rest)
    return read_large


def next_read_size(read_size: int, buffered: int, read_large: bool) -> int:
    """rospy's next read size for a subscriber connection that read with `read_size`, after read_raw_messages took
    what `buffered` bytes held (`read_large`: a message came straight from the socket). See SUBSCRIBER_READ_BYTES."""
    if read_large:
        return SUBSCRIBER_READ_BYTES
    if buffered >= read_size:  # the last read came full: more is waiting than a read takes
        return FLOOD_READ_BYTES
    return read_size


def _receive_into(sock: socket.socket, view: memoryview) -> None:
    while view:
        try:
            received = sock.recv_into(view)
        except OSError as error:
            raise TransportTerminated(f"receiving from the publisher failed: {error}") from None
        if not received:
            raise TransportTerminated("the publisher closed the connection")
        view = view[received:]


def install_raw_reader() -> None:
    """rospy's subscriber connections of raw classes read with read_raw_messages, with a read size that follows the
    traffic (next_read_size; the endpoint's own process: every other class keeps rospy's way). Messages read
    straight from the socket are not in rospy's byte statistics."""
    subscriber_protocol = rospy.impl.tcpros_pubsub.TCPROSSub
    rospy_read = subscriber_protocol.read_messages
    if getattr(rospy_read, "reads_raw", False):
        return

    def read_messages(protocol: Any, buffer: io.BytesIO, messages: list, sock: socket.socket) -> None:
        raw = protocol.recv_data_class
        if protocol.queue_size is None and isinstance(raw, type) and issubclass(raw, RawMessage):
            buffered = buffer.tell()
            read_large = read_raw_messages(buffer, messages, sock, raw)
            protocol.buff_size = next_read_size(protocol.buff_size, buffered, read_large)
        else:
            rospy_read(protocol, buffer, messages, sock)

    read_messages.reads_raw = True  # type: ignore[attr-defined]
    subscriber_protocol.read_messages = read_messages
