"""The ROS-TCP protocol v0.7.0 (ROS 1 flavour), sans I/O: framing and system commands.

A frame is `u32 LE length + destination (UTF-8) + u32 LE length + payload`. Destination "" with an empty
payload is a keepalive; destinations starting with "__" are system commands whose payload is one JSON object;
anything else is a topic or service name with a plain ROS 1 serialized payload.

This module imports neither socket nor rospy: it turns bytes into frames and frames into bytes, and checks every
length against its limit *before* allocating for it.
"""
from __future__ import annotations

import json
import struct
from dataclasses import dataclass
from typing import Any, Union

PROTOCOL_VERSION = "v0.7.0"
ROS_DISTRO_PROTOCOL = "ROS1"
MAX_DESTINATION_BYTES = 1024
DEFAULT_MAX_PAYLOAD_BYTES = 64 * 1024 * 1024

_U32 = struct.Struct("<I")


class ProtocolError(ValueError):
    """Input that breaks the protocol; the message names the offending command, field or value."""


class FramingError(ProtocolError):
    """The byte stream cannot be framed any more (a length over its limit): the connection must close."""


@dataclass(frozen=True, slots=True)
class Frame:
    destination: str
    payload: bytes

    @property
    def is_keepalive(self) -> bool:
        return self.destination == "" and not self.payload

    @property
    def is_syscommand(self) -> bool:
        return self.destination.startswith("__")


@dataclass(frozen=True, slots=True)
class BadFrame:
    """A frame whose framing was intact but whose destination is not UTF-8; the stream stays usable."""

    reason: str


class FrameDecoder:
    """Incremental decoder: feed it any fragments of the stream, get back the complete frames.

    Fragmentation and coalescing are both handled: a frame may arrive one byte at a time, and one `feed` may
    carry many frames. After a FramingError the decoder refuses further input (the stream position is lost).
    """

    def __init__(
        self,
        max_payload_bytes: int = DEFAULT_MAX_PAYLOAD_BYTES,
        max_destination_bytes: int = MAX_DESTINATION_BYTES,
    ) -> None:
        self.max_payload_bytes = max_payload_bytes
        self.max_destination_bytes = max_destination_bytes
        self._buffer = bytearray()
        self._failed: FramingError | None = None

    @property
    def buffered_bytes(self) -> int:
        return len(self._buffer)

    def feed(self, data: bytes) -> list[Frame | BadFrame]:
        if self._failed is not None:
            raise self._failed
        self._buffer += data
        frames: list[Frame | BadFrame] = []
        offset = 0
        buffer = self._buffer
        while True:
            frame_end, item = self._parse_one(buffer, offset)
            if item is None:
                break
            frames.append(item)
            offset = frame_end
        if offset:
            del buffer[:offset]
        return frames

    def _parse_one(self, buffer: bytearray, offset: int) -> tuple[int, Frame | BadFrame | None]:
        available = len(buffer) - offset
        if available < 4:
            return offset, None
        (destination_length,) = _U32.unpack_from(buffer, offset)
        if destination_length > self.max_destination_bytes:
            self._fail(
                f"destination length {destination_length} exceeds the limit of {self.max_destination_bytes} bytes"
            )
        payload_length_at = offset + 4 + destination_length
        if len(buffer) < payload_length_at + 4:
            return offset, None
        (payload_length,) = _U32.unpack_from(buffer, payload_length_at)
        if payload_length > self.max_payload_bytes:
            destination = bytes(buffer[offset + 4 : payload_length_at]).decode("utf-8", "replace")
            self._fail(
                f"payload length {payload_length} for destination {destination!r} exceeds the limit of "
                f"{self.max_payload_bytes} bytes"
            )
        payload_at = payload_length_at + 4
        frame_end = payload_at + payload_length
        if len(buffer) < frame_end:
            return offset, None
        raw_destination = bytes(buffer[offset + 4 : payload_length_at]).rstrip(b"\0")
        payload = bytes(buffer[payload_at:frame_end])
        try:
            destination = raw_destination.decode("utf-8")
        except UnicodeDecodeError:
            return frame_end, BadFrame(f"destination {raw_destination[:64]!r} is not valid UTF-8")
        return frame_end, Frame(destination, payload)

    def _fail(self, reason: str) -> None:
        self._failed = FramingError(reason)
        self._buffer = bytearray()
        raise self._failed


def encode_frame(destination: str, payload: bytes) -> bytes:
    encoded_destination = destination.encode("utf-8")
    return b"".join(
        (_U32.pack(len(encoded_destination)), encoded_destination, _U32.pack(len(payload)), payload)
    )


KEEPALIVE_FRAME = encode_frame("", b"")


def encode_syscommand(command: str, params: dict[str, Any]) -> bytes:
    """A system command frame; compact JSON with fields in the given order, as the Unity client writes them."""
    if not command.startswith("__"):
        raise ProtocolError(f"system command {command!r} must start with '__'")
    return encode_frame(command, json.dumps(params, separators=(",", ":")).encode("utf-8"))


def handshake_frame() -> bytes:
    # Byte for byte what the v0.7.0 endpoint sends: json.dumps with its default ", " and ": " separators.
    # metadata is a JSON *string* holding an object: the client parses it a second time.
    metadata = json.dumps({"protocol": ROS_DISTRO_PROTOCOL})
    body = json.dumps({"version": PROTOCOL_VERSION, "metadata": metadata})
    return encode_frame("__handshake", body.encode("utf-8"))


def log_frame(text: str) -> bytes:
    return encode_syscommand("__log", {"text": text})


def warn_frame(text: str) -> bytes:
    return encode_syscommand("__warn", {"text": text})


def error_frame(text: str) -> bytes:
    return encode_syscommand("__error", {"text": text})


# ---------------------------------------------------------------------------------------------------------------
# System commands, client -> endpoint


@dataclass(frozen=True, slots=True)
class Subscribe:
    topic: str
    message_name: str


@dataclass(frozen=True, slots=True)
class Publish:
    topic: str
    message_name: str
    queue_size: int = 10
    latch: bool = False


@dataclass(frozen=True, slots=True)
class RosService:
    topic: str
    message_name: str


@dataclass(frozen=True, slots=True)
class UnityService:
    topic: str
    message_name: str


@dataclass(frozen=True, slots=True)
class Request:
    srv_id: int


@dataclass(frozen=True, slots=True)
class Response:
    srv_id: int


@dataclass(frozen=True, slots=True)
class TopicList:
    pass


@dataclass(frozen=True, slots=True)
class Remove:
    kind: str  # "subscriber" | "publisher" | "ros_service" | "unity_service"
    topic: str


@dataclass(frozen=True, slots=True)
class Auth:
    token: str


SysCommand = Union[Subscribe, Publish, RosService, UnityService, Request, Response, TopicList, Remove, Auth]

REMOVE_COMMANDS = {
    "__remove_subscriber": "subscriber",
    "__remove_publisher": "publisher",
    "__remove_ros_service": "ros_service",
    "__remove_unity_service": "unity_service",
}

# command -> (required fields with types, optional fields with types)
_FIELDS: dict[str, tuple[dict[str, type], dict[str, type]]] = {
    "__subscribe": ({"topic": str, "message_name": str}, {}),
    "__publish": ({"topic": str, "message_name": str}, {"queue_size": int, "latch": bool}),
    "__ros_service": ({"topic": str, "message_name": str}, {}),
    "__unity_service": ({"topic": str, "message_name": str}, {}),
    "__request": ({"srv_id": int}, {}),
    "__response": ({"srv_id": int}, {}),
    "__topic_list": ({}, {}),
    "__auth": ({"token": str}, {}),
    **{command: ({"topic": str}, {}) for command in REMOVE_COMMANDS},
}
CLIENT_COMMANDS = frozenset(_FIELDS)


def parse_syscommand(frame: Frame) -> SysCommand:
    """Validate a system command frame and return it as a typed command; ProtocolError names what is wrong."""
    command = frame.destination
    fields = _FIELDS.get(command)
    if fields is None:
        raise ProtocolError(f"unknown system command {command!r}")
    params = _parse_json_object(command, frame.payload)
    required, optional = fields
    for name, expected in required.items():
        if name not in params:
            raise ProtocolError(f"{command}: missing field {name!r}")
    unexpected = sorted(set(params) - set(required) - set(optional))
    if unexpected:
        raise ProtocolError(f"{command}: unexpected field(s) {', '.join(map(repr, unexpected))}")
    for name, expected in {**required, **optional}.items():
        if name in params:
            _check_type(command, name, params[name], expected)
    if "topic" in params:
        _check_name(command, "topic", params["topic"])
    if "message_name" in params:
        _check_message_name(command, params["message_name"])

    if command == "__subscribe":
        return Subscribe(params["topic"], params["message_name"])
    if command == "__publish":
        queue_size = params.get("queue_size", 10)
        if queue_size < 0:
            raise ProtocolError(f"{command}: field 'queue_size' must be >= 0, got {queue_size}")
        return Publish(params["topic"], params["message_name"], queue_size, params.get("latch", False))
    if command == "__ros_service":
        return RosService(params["topic"], params["message_name"])
    if command == "__unity_service":
        return UnityService(params["topic"], params["message_name"])
    if command == "__request":
        return Request(params["srv_id"])
    if command == "__response":
        return Response(params["srv_id"])
    if command == "__topic_list":
        return TopicList()
    if command == "__auth":
        return Auth(params["token"])
    return Remove(REMOVE_COMMANDS[command], params["topic"])


def parse_json_params(command: str, payload: bytes) -> dict[str, Any]:
    """The JSON object of any system command (also endpoint -> client ones, for the client side)."""
    return _parse_json_object(command, payload)


def _parse_json_object(command: str, payload: bytes) -> dict[str, Any]:
    try:
        params = json.loads(payload.decode("utf-8")) if payload else {}
    except UnicodeDecodeError:
        raise ProtocolError(f"{command}: payload is not valid UTF-8") from None
    except json.JSONDecodeError as error:
        raise ProtocolError(f"{command}: malformed JSON ({error.msg} at position {error.pos})") from None
    if not isinstance(params, dict):
        raise ProtocolError(f"{command}: payload must be a JSON object, got {type(params).__name__}")
    return params


def _check_type(command: str, name: str, value: Any, expected: type) -> None:
    # bool is a subclass of int in Python; a srv_id of `true` is still wrong.
    if expected is int and (isinstance(value, bool) or not isinstance(value, int)):
        raise ProtocolError(f"{command}: field {name!r} must be an integer, got {value!r}")
    if not isinstance(value, expected):
        raise ProtocolError(f"{command}: field {name!r} must be a {expected.__name__}, got {value!r}")


def _check_name(command: str, field: str, name: str) -> None:
    if not name or name.startswith("__") or any(c.isspace() or c == "\0" for c in name):
        raise ProtocolError(f"{command}: field {field!r} is not a valid ROS name: {name!r}")


def _check_message_name(command: str, message_name: str) -> None:
    package, _, type_name = message_name.partition("/")
    if not package or not type_name or "/" in type_name or not (package + type_name).replace("_", "").isalnum():
        raise ProtocolError(f"{command}: field 'message_name' must look like 'package/Type', got {message_name!r}")
