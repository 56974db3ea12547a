"""What clients have bridged, as the endpoint keeps it: each client's registrations, and what the topic and service
tables share (the lock, the names a client may use, the check for room).

The tables themselves live in bridge.topics and bridge.services; bridge.server owns one of each and hands them this.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, TypeVar

from bridge.config import EndpointConfig
from bridge.errors import RequestRefused
from bridge.ros.publisher import RawPublisher
from bridge.ros.raw_types import RosError
from bridge.ros.service_proxy import RawServiceProxy

if TYPE_CHECKING:
    from bridge.connection.session import ClientSession

__all__ = ["ClientRegistrations", "RoomCheck", "Bridged", "made_for_client"]

_Made = TypeVar("_Made")


@dataclass
class ClientRegistrations:
    """What one client registered, as the endpoint keeps it (the session knows none of it)."""

    subscriptions: dict[str, str] = field(default_factory=dict)  # resolved topic -> topic as the client spells it
    publishers: dict[str, tuple[str, RawPublisher]] = field(default_factory=dict)  # client topic -> (resolved, ...)
    ros_services: dict[str, RawServiceProxy] = field(default_factory=dict)  # client's service name -> proxy
    unity_services: set[str] = field(default_factory=set)  # resolved names

    def count(self) -> int:
        return len(self.subscriptions) + len(self.publishers) + len(self.ros_services) + len(self.unity_services)


# (session, command, resolved name, already registered by the client, would make a new ROS object): refuses with
# RequestRefused when there is no room. Called with the lock held.
RoomCheck = Callable[["ClientSession", str, str, bool, bool], None]


@dataclass
class Bridged:
    """The state the endpoint's tables share: its lock (guards every table and registration), each client's
    registrations, the ROS graph, the settings and the room check."""

    ros: Any  # bridge.ros.graph.RosGraph
    config: EndpointConfig
    room: RoomCheck
    lock: threading.RLock = field(default_factory=threading.RLock)
    clients: dict[ClientSession, ClientRegistrations] = field(default_factory=dict)

    def permitted(self, name: str) -> str:
        """The resolved name, when the settings' allow/deny lists permit it; RequestRefused otherwise."""
        resolved: str = self.ros.resolve(name)
        if not self.config.permits(resolved):
            raise RequestRefused(f"topic {resolved} is not permitted by the endpoint's allow/deny lists")
        return resolved

    def payload_problem(self, type_name: str, payload: bytes, service_part: str = "") -> str | None:
        """Why `payload` is not exactly one `type_name` message (or, given `service_part` "request" or "response",
        one such part of a `type_name` service); None when it is, or when the settings skip the check."""
        if not self.config.validate_payloads:
            return None
        try:
            if service_part:
                self.ros.types.validate_service(type_name, service_part, payload)
            else:
                self.ros.types.validate(type_name, payload)
        except RosError as error:
            return str(error)
        return None


def made_for_client(make: Callable[[], _Made]) -> _Made:
    """A ROS object made for a client's request; a ROS-side failure is that request's refusal."""
    try:
        return make()
    except RosError as error:
        raise RequestRefused(str(error)) from None
