"""ROS-TCP framing, sans I/O: `u32 LE length + destination (UTF-8) + u32 LE length + payload`, split out of any
fragments of a stream, with every length checked against its limit before anything is allocated for it.
"""

from __future__ import annotations

import json
import struct
from typing import Any, Tuple

from bridge.protocol.events import FramingError, LocalProtocolError

__all__ = [
    "MAX_DESTINATION_BYTES",
    "DEFAULT_MAX_PAYLOAD_BYTES",
    "RawFrame",
    "FrameDecoder",
    "decode_destination",
    "not_utf8",
    "encode_frame",
    "encode_syscommand",
    "KEEPALIVE_FRAME",
    "LARGE_PAYLOAD_BYTES",
]

MAX_DESTINATION_BYTES = 1024
DEFAULT_MAX_PAYLOAD_BYTES = 64 * 1024 * 1024
# Payloads at least this large are collected piece by piece once their frame header is in (see _LargePayload).
LARGE_PAYLOAD_BYTES = 64 * 1024

_U32 = struct.Struct("<I")


RawFrame = Tuple[bytes, bytes]  # (destination bytes, payload) as framed, before the destination is decoded


class FrameDecoder:
    """Incremental framing: feed it any fragments of the stream, get back the complete frames.

    Fragmentation and coalescing are both handled: a frame may arrive one byte at a time, and one feed may carry
    many frames. After a FramingError the decoder refuses further input (the stream position is lost).
    """

    def __init__(
        self,
        max_payload_bytes: int = DEFAULT_MAX_PAYLOAD_BYTES,
        max_destination_bytes: int = MAX_DESTINATION_BYTES,
    ) -> None:
        self.max_payload_bytes = max_payload_bytes
        self.max_destination_bytes = max_destination_bytes
        self._buffer = bytearray()
        self._large: _LargePayload | None = None  # a large payload being collected, once its header is in
        self._failed: FramingError | None = None

    @property
    def buffered_bytes(self) -> int:
        """Bytes received of frames not yet complete."""
        return len(self._buffer) + (self._large.received if self._large is not None else 0)

    def feed_raw(self, data: bytes) -> tuple[list[RawFrame], FramingError | None]:
        """The complete frames with undecoded destinations, and the FramingError that ended the stream if one did:
        the frames before it are still returned. Raises the FramingError again once the stream has failed."""
        if self._failed is not None:
            raise self._failed
        frames: list[RawFrame] = []
        rest: bytes | memoryview = data
        if self._large is not None:
            rest = self._large.take(data, frames)
            if self._large.missing:
                return frames, None
            self._large = None
        self._buffer += rest
        buffer = self._buffer
        offset = 0
        try:
            while True:
                frame_end, frame = self._parse_one(buffer, offset)
                if frame is None:
                    break
                frames.append(frame)
                offset = frame_end
        except FramingError as error:
            # Kept without its traceback: that would keep this frame's locals, the whole buffer among them.
            self._failed = error.with_traceback(None)
            self._buffer = bytearray()
            return frames, self._failed
        if offset:
            del buffer[:offset]
        self._large = _LargePayload.begun(buffer)
        return frames, None

    def _parse_one(self, buffer: bytearray, offset: int) -> tuple[int, RawFrame | None]:
        if len(buffer) - offset < 4:
            return offset, None
        (destination_length,) = _U32.unpack_from(buffer, offset)
        if destination_length > self.max_destination_bytes:
            raise FramingError(
                f"destination length {destination_length} exceeds the limit of {self.max_destination_bytes} bytes"
            )
        payload_length_at = offset + 4 + destination_length
        if len(buffer) < payload_length_at + 4:
            return offset, None
        (payload_length,) = _U32.unpack_from(buffer, payload_length_at)
        if payload_length > self.max_payload_bytes:
            destination = bytes(buffer[offset + 4 : payload_length_at]).decode("utf-8", "replace")
            raise FramingError(
                f"payload length {payload_length} for destination {destination!r} exceeds the limit of "
                f"{self.max_payload_bytes} bytes"
            )
        payload_at = payload_length_at + 4
        frame_end = payload_at + payload_length
        if len(buffer) < frame_end:
            return offset, None
        raw_destination = bytes(buffer[offset + 4 : payload_length_at])
        if payload_length < LARGE_PAYLOAD_BYTES:
            return frame_end, (raw_destination, bytes(buffer[payload_at:frame_end]))
        with memoryview(buffer) as view:  # one copy, not two (a bytearray slice, then bytes of it)
            return frame_end, (raw_destination, bytes(view[payload_at:frame_end]))


class _LargePayload:
    """A payload of at least LARGE_PAYLOAD_BYTES whose frame header has arrived: the pieces of it the stream brings
    are kept as they come and joined once, when it is complete (one copy of its bytes, where appending each piece
    to the decoder's buffer and cutting the payload out of it made three)."""

    __slots__ = ("destination", "parts", "missing", "received")

    def __init__(self, destination: bytes, first_part: bytes, payload_length: int, header_length: int) -> None:
        self.destination = destination
        self.parts: list[bytes | memoryview] = [first_part] if first_part else []
        self.missing = payload_length - len(first_part)
        self.received = header_length + len(first_part)  # bytes of the frame received so far

    @classmethod
    def begun(cls, buffer: bytearray) -> _LargePayload | None:
        """The large payload whose frame begins `buffer` (which holds no complete frame), taking the buffer's
        bytes; None (buffer untouched) when the buffer does not begin such a frame's header and payload."""
        if len(buffer) < 8:
            return None
        (destination_length,) = _U32.unpack_from(buffer, 0)
        payload_at = 4 + destination_length + 4
        if len(buffer) < payload_at:
            return None
        (payload_length,) = _U32.unpack_from(buffer, payload_at - 4)
        if payload_length < LARGE_PAYLOAD_BYTES:
            return None
        large = cls(bytes(buffer[4 : payload_at - 4]), bytes(buffer[payload_at:]), payload_length, payload_at)
        buffer.clear()
        return large

    def take(self, data: bytes, frames: list[RawFrame]) -> bytes | memoryview:
        """Keep what `data` holds of the payload, appending the frame to `frames` once complete; the rest of
        `data` (after this frame) is returned."""
        if len(data) <= self.missing:
            part: bytes | memoryview = data
            rest: bytes | memoryview = b""
        else:
            view = memoryview(data)
            part, rest = view[: self.missing], view[self.missing :]
        self.parts.append(part)
        self.missing -= len(part)
        self.received += len(part)
        if not self.missing:
            parts = self.parts
            payload = parts[0] if len(parts) == 1 and type(parts[0]) is bytes else b"".join(parts)
            frames.append((self.destination, payload))  # type: ignore[arg-type]
            self.parts = []
        return rest


def decode_destination(raw: bytes) -> str:
    """The destination as text; trailing NULs (some clients pad) are not part of it. UnicodeDecodeError if bad."""
    return raw.rstrip(b"\0").decode("utf-8")


def not_utf8(raw_destination: bytes) -> str:
    shown = raw_destination.rstrip(b"\0")[:64]
    return f"destination {shown!r} is not valid UTF-8"


def encode_frame(destination: str, payload: bytes) -> bytes:
    encoded_destination = destination.encode("utf-8")
    return b"".join((_U32.pack(len(encoded_destination)), encoded_destination, _U32.pack(len(payload)), payload))


def encode_syscommand(command: str, params: dict[str, Any]) -> bytes:
    """A system command frame with any JSON object (compact, fields in the given order, as Unity writes them)."""
    if not command.startswith("__"):
        raise LocalProtocolError(f"system command {command!r} must start with '__'")
    return encode_frame(command, json.dumps(params, separators=(",", ":")).encode("utf-8"))


KEEPALIVE_FRAME = encode_frame("", b"")
