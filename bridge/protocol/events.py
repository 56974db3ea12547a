"""The protocol's vocabulary: what one end of a ROS-TCP connection can say to the other, as frozen dataclasses under
one base (`Event`), and the errors of either side. bridge.protocol turns them into bytes and back.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from bridge.errors import BridgeError

__all__ = [
    "ProtocolError",
    "LocalProtocolError",
    "RemoteProtocolError",
    "FramingError",
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
    "REMOVE_KINDS",
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
    "PROTOCOL_VERSION",
    "ROS_DISTRO_PROTOCOL",
]

PROTOCOL_VERSION = "v0.7.0"
ROS_DISTRO_PROTOCOL = "ROS1"


class ProtocolError(BridgeError, ValueError):
    """Something that breaks the protocol; the message names the offending command, field or value."""


class LocalProtocolError(ProtocolError):
    """We were about to send something the protocol does not allow (a bug of ours, never of the peer)."""


class RemoteProtocolError(ProtocolError):
    """The peer sent something the protocol does not allow. `srv_id` names the service call it concerns, if any;
    `fatal` means the byte stream cannot be framed any more and the connection must close."""

    def __init__(self, reason: str, srv_id: int | None = None, fatal: bool = False) -> None:
        super().__init__(reason)
        self.srv_id = srv_id
        self.fatal = fatal


class FramingError(RemoteProtocolError):
    """A length over its limit: the stream position is lost."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason, fatal=True)


class Event:
    """Something one end says to the other. Every event is a frozen dataclass."""

    __slots__ = ()


@dataclass(frozen=True)
class Keepalive(Event):
    """An empty frame; the client sends one after each second without sending. Received keepalives are not
    reported as events: they mean nothing beyond the connection being alive."""


@dataclass(frozen=True)
class Handshake(Event):
    """The endpoint's first frame. `metadata` is sent as a JSON *string* holding an object (Unity parses it twice)."""

    version: str
    metadata: dict[str, Any]

    @property
    def is_compatible(self) -> bool:
        """What Unity's connector checks: a v0.7.x endpoint speaking ROS 1 (a mismatch is only logged there)."""
        return self.version.startswith("v0.7.") and self.metadata.get("protocol") == ROS_DISTRO_PROTOCOL


@dataclass(frozen=True)
class TopicMessage(Event):
    """One ROS 1 serialized message on a topic, either way. The payload is carried untouched."""

    __slots__ = ("topic", "payload")
    topic: str
    payload: bytes


@dataclass(frozen=True)
class ServiceRequest(Event):
    """A service call, with its request body: client -> endpoint calls a ROS service (ids from 101); endpoint ->
    client calls a service the client implements (ids from 1001). On the wire, `__request` and the body frame."""

    srv_id: int
    service: str
    payload: bytes


@dataclass(frozen=True)
class ServiceResponse(Event):
    """The answer to the ServiceRequest with the same `srv_id`, with its response body."""

    srv_id: int
    service: str
    payload: bytes


@dataclass(frozen=True)
class Subscribe(Event):
    """Forward ROS messages on `topic` to this client. `queue_size`: newer connectors may send one."""

    topic: str
    message_name: str
    queue_size: int | None = None


@dataclass(frozen=True)
class Publish(Event):
    """This client will publish on `topic`."""

    topic: str
    message_name: str
    queue_size: int = 10
    latch: bool = False


@dataclass(frozen=True)
class RosService(Event):
    """This client will call the ROS service `topic` of type `message_name` (no Request/Response suffix)."""

    topic: str
    message_name: str


@dataclass(frozen=True)
class UnityService(Event):
    """This client implements the service `topic` for ROS."""

    topic: str
    message_name: str


REMOVE_KINDS = ("subscriber", "publisher", "ros_service", "unity_service")


@dataclass(frozen=True)
class Remove(Event):
    """Undo a registration: `kind` is one of REMOVE_KINDS (`__remove_<kind>` on the wire)."""

    kind: str
    topic: str


@dataclass(frozen=True)
class TopicListQuery(Event):
    """Ask for the ROS graph's topics and their types."""


@dataclass(frozen=True)
class TopicList(Event):
    """The answer to TopicListQuery: parallel tuples of topic names and type names."""

    topics: tuple[str, ...]
    types: tuple[str, ...]


@dataclass(frozen=True)
class Auth(Event):
    """Ours, not Unity's: the shared secret, as the first command, when the endpoint asks for one."""

    token: str


@dataclass(frozen=True)
class Ping(Event):
    """Newer connectors' ROSConnection.Ping: `request_time` is the client's clock, echoed back unchanged.
    `round_trip` (ours, optional): the client's measure of its previous ping, for the endpoint's diagnostics."""

    request_time: str
    round_trip: float | None = None


@dataclass(frozen=True)
class PingResponse(Event):
    """The answer to Ping: its `request_time`, and (ours) the endpoint's ROS time in seconds when it answered, from
    which a client estimates the offset of its clock to ROS time."""

    request_time: str
    ros_time: float | None = None


@dataclass(frozen=True)
class Log(Event):
    text: str


@dataclass(frozen=True)
class Warn(Event):
    text: str


@dataclass(frozen=True)
class Error(Event):
    """A refusal or failure, as text. `srv_id` (ours, beside the text) names the service call that will not
    complete, so a client can fail it at once; Unity's connector reads only the text."""

    text: str
    srv_id: int | None = None


@dataclass(frozen=True)
class IgnoredFields(Event):
    """A command carried fields this side does not know (a newer peer's): the command is carried out without them.
    Reported once per command and field on a connection, before the command's own event."""

    command: str
    fields: tuple[str, ...]


@dataclass(frozen=True)
class InvalidInput(Event):
    """The peer broke the protocol (see RemoteProtocolError). Not fatal unless `error.fatal`: the frames after it
    are read as usual."""

    error: RemoteProtocolError
