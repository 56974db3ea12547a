"""The ROS-TCP protocol v0.7.0 (ROS 1 flavour), sans I/O: framing, events, and the conversation of both ends.

A frame is `u32 LE length + destination (UTF-8) + u32 LE length + payload`. Destination "" with an empty payload
is a keepalive; destinations starting with "__" are system commands whose payload is one JSON object; anything
else is a topic or service name with a plain ROS 1 serialized payload. A `__request` or `__response` header says
that the very next frame is a service body.

Its modules, each sans I/O: events (what either end can say), framing (frames out of a stream's fragments),
commands (the system commands' JSON and every event's bytes), names (ROS graph and type names), conversation (one
connection's state, for either end), layout (a ROS 1 serialized payload's structure), client_answers (what a
client waits for), and websocket (the same frames over WebSocket, on the optional wsproto: imported by itself, never
from here). None of them reads a socket or touches ROS (none imports socket or rospy), so every rule of the protocol
is tested without I/O. Lengths are checked against their limits *before* anything is allocated.

`Conversation(Role.ENDPOINT)` or `Conversation(Role.CLIENT)` holds the state of one connection (has the handshake
been seen, is a service body due) and nothing else: `receive_data(bytes)` gives typed events, `send(event)` gives
bytes. The names below are the protocol's public surface, used as `from bridge import protocol`.
"""

from __future__ import annotations

from bridge.protocol.commands import CLIENT_COMMANDS, MAX_JSON_NESTING, encode, handshake
from bridge.protocol.conversation import Conversation, Role
from bridge.protocol.events import (
    PROTOCOL_VERSION,
    ROS_DISTRO_PROTOCOL,
    Auth,
    Error,
    Event,
    FramingError,
    Handshake,
    IgnoredFields,
    InvalidInput,
    Keepalive,
    LocalProtocolError,
    Log,
    Ping,
    PingResponse,
    ProtocolError,
    Publish,
    RemoteProtocolError,
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
)
from bridge.protocol.framing import (
    DEFAULT_MAX_PAYLOAD_BYTES,
    KEEPALIVE_FRAME,
    MAX_DESTINATION_BYTES,
    FrameDecoder,
    encode_frame,
    encode_syscommand,
)

# The protocol's whole public surface, in one place (the events and framing modules hold the parts).
__all__ = [
    "PROTOCOL_VERSION",
    "ROS_DISTRO_PROTOCOL",
    "MAX_DESTINATION_BYTES",
    "MAX_JSON_NESTING",
    "DEFAULT_MAX_PAYLOAD_BYTES",
    "ProtocolError",
    "LocalProtocolError",
    "RemoteProtocolError",
    "FramingError",
    "FrameDecoder",
    "encode_frame",
    "encode_syscommand",
    "KEEPALIVE_FRAME",
    "Event",
    "Keepalive",
    "Handshake",
    "TopicMessage",
    "ServiceRequest",
    "ServiceResponse",
    "Subscribe",
    "Publish",
    "RosService",
    "UnityService",
    "Remove",
    "TopicListQuery",
    "TopicList",
    "Auth",
    "Ping",
    "PingResponse",
    "Log",
    "Warn",
    "Error",
    "IgnoredFields",
    "InvalidInput",
    "Role",
    "Conversation",
    "encode",
    "handshake",
    "CLIENT_COMMANDS",
]
