"""The conversation of either end of a ROS-TCP connection, sans I/O: `Conversation(Role.ENDPOINT)` or
`Conversation(Role.CLIENT)` turns the peer's bytes into typed events and ours into bytes (bridge.protocol says the
protocol's rules; its framing is bridge.protocol.framing's, its system commands bridge.protocol.commands')."""

from __future__ import annotations

import enum

from bridge.protocol.commands import (
    SENT_BY_CLIENT,
    SENT_BY_ENDPOINT,
    SERVICE_HEADER,
    SERVICE_HEADERS,
    ServiceEvent,
    command_params,
    encode,
    json_object,
)
from bridge.protocol.events import (
    Auth,
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
    MAX_DESTINATION_BYTES,
    FrameDecoder,
    decode_destination,
    not_utf8,
)
from bridge.protocol.names import graph_name_problem

__all__ = ["Role", "Conversation"]


# --- the conversation --------------------------------------------------------------------------------------------


class Role(enum.Enum):
    ENDPOINT = "endpoint"
    CLIENT = "client"


# Events that name a topic or service (checked ASCII by then, so a character is a byte)
_NAMED = (Subscribe, Publish, RosService, UnityService, Remove)
_PARSERS = {Role.CLIENT: SENT_BY_CLIENT, Role.ENDPOINT: SENT_BY_ENDPOINT}
_EVENTS_SENT_BY: dict[Role, tuple[type[Event], ...]] = {
    Role.CLIENT: (
        Keepalive,
        TopicMessage,
        ServiceRequest,
        ServiceResponse,
        Subscribe,
        Publish,
        RosService,
        UnityService,
        Remove,
        TopicListQuery,
        Auth,
        Ping,
    ),
    Role.ENDPOINT: (
        Handshake,
        TopicMessage,
        ServiceRequest,
        ServiceResponse,
        TopicList,
        PingResponse,
        Log,
        Warn,
        Error,
    ),
}


class Conversation:
    """One connection's protocol state, for either end (`our_role`).

    `receive_data` turns the peer's bytes into events, in order; the peer's mistakes come as InvalidInput events in
    their place, so one bad frame never costs the frames around it. `send` turns our events into bytes and raises
    LocalProtocolError for anything our role may not say. The receiving side is meant for one thread (the
    connection's reader); `send` keeps no state and may be called from any thread.
    """

    def __init__(
        self,
        our_role: Role,
        max_payload_bytes: int = DEFAULT_MAX_PAYLOAD_BYTES,
        max_destination_bytes: int = MAX_DESTINATION_BYTES,
    ) -> None:
        self.our_role = our_role
        self.their_role = Role.CLIENT if our_role is Role.ENDPOINT else Role.ENDPOINT
        self._decoder = FrameDecoder(max_payload_bytes, max_destination_bytes)
        self._max_destination_bytes = max_destination_bytes
        self._their_commands = _PARSERS[self.their_role]
        self._may_send = _EVENTS_SENT_BY[our_role]
        # The receiving side's whole state:
        self.awaiting_handshake = our_role is Role.CLIENT  # a client's first frame must be the handshake
        self.pending_service: tuple[ServiceEvent, int] | None = None
        self.frames_received = 0
        self._reported_fields: set[tuple[str, str]] = set()  # (command, field) already reported as IgnoredFields

    @property
    def buffered_bytes(self) -> int:
        """Bytes received of a frame not yet complete."""
        return self._decoder.buffered_bytes

    # --- receiving ---------------------------------------------------------------------------------------------
    def receive_data(self, data: bytes) -> list[Event]:
        """The events in `data` (any fragment of the stream), in order. After an InvalidInput that is fatal (a
        length over its limit), the stream position is lost: a further call raises that error."""
        frames, failure = self._decoder.feed_raw(data)
        self.frames_received += len(frames)
        events: list[Event] = []
        for raw_destination, payload in frames:
            # The hot path first: a topic message, outside a service exchange.
            if (
                self.pending_service is None
                and not self.awaiting_handshake
                and raw_destination[:2] != b"__"
                and raw_destination
            ):
                try:
                    events.append(TopicMessage(decode_destination(raw_destination), payload))
                except UnicodeDecodeError:
                    events.append(InvalidInput(RemoteProtocolError(f"frame dropped: {not_utf8(raw_destination)}")))
                continue
            events.extend(self._receive_frame(raw_destination, payload))
        if failure is not None:
            self.pending_service = None
            events.append(InvalidInput(failure))
        return events

    def _receive_frame(self, raw_destination: bytes, payload: bytes) -> tuple[Event, ...]:
        """The events of one frame other than a plain topic message: none (a keepalive, a service header), one, or
        IgnoredFields and then the command's own."""
        if not raw_destination and not payload:
            return ()  # a keepalive, wherever it comes (even between a service header and its body)
        try:
            destination = decode_destination(raw_destination)
        except UnicodeDecodeError:
            srv_id = self._drop_pending_service()
            return (InvalidInput(RemoteProtocolError(f"frame dropped: {not_utf8(raw_destination)}", srv_id)),)
        if self.pending_service is not None:
            kind, srv_id = self.pending_service
            self.pending_service = None
            return (kind(srv_id, destination, payload),)
        if self.awaiting_handshake and destination != "__handshake":
            return (
                InvalidInput(
                    RemoteProtocolError(
                        f"the endpoint's first frame must be __handshake, got {destination!r}; frame dropped"
                    )
                ),
            )
        if not destination.startswith("__"):
            return (TopicMessage(destination, payload),)
        service_kind = SERVICE_HEADERS.get(destination)
        spec = SERVICE_HEADER if service_kind is not None else self._their_commands.get(destination)
        try:
            if spec is None:
                raise ProtocolError(f"unknown system command {destination!r}")
            params = json_object(destination, payload)
            event = spec.parse(destination, params)
            if isinstance(event, _NAMED) and len(event.topic) > self._max_destination_bytes:
                # One limit for a name everywhere: a topic a client registers is one it can send frames to.
                raise ProtocolError(
                    f"{destination}: field 'topic' is not a valid ROS name: {event.topic[:64]!r}... "
                    f"{graph_name_problem(event.topic, self._max_destination_bytes)}"
                )
        except ProtocolError as error:
            return (InvalidInput(RemoteProtocolError(str(error))),)
        ignored = self._newly_ignored(destination, spec.unknown_fields(params))
        if service_kind is not None:
            self.pending_service = (service_kind, params["srv_id"])
            return ignored  # the service event comes with the body, the next frame
        if isinstance(event, Handshake):
            self.awaiting_handshake = False
        return (*ignored, event)

    def _newly_ignored(self, command: str, fields: tuple[str, ...]) -> tuple[Event, ...]:
        """IgnoredFields for the fields not reported before on this connection, if any."""
        new = tuple(name for name in fields if (command, name) not in self._reported_fields)
        if not new:
            return ()
        self._reported_fields.update((command, name) for name in new)
        return (IgnoredFields(command, new),)

    def _drop_pending_service(self) -> int | None:
        if self.pending_service is None:
            return None
        srv_id = self.pending_service[1]
        self.pending_service = None
        return srv_id

    # --- sending -----------------------------------------------------------------------------------------------
    def send(self, event: Event) -> bytes:
        """The bytes that say `event` to the peer; LocalProtocolError if our role may not say it, or says it
        wrongly (the same field checks as on receiving)."""
        if not isinstance(event, self._may_send):
            raise LocalProtocolError(f"the {self.our_role.value} does not send {type(event).__name__}")
        if isinstance(event, TopicMessage) and (not event.topic or event.topic.startswith("__")):
            raise LocalProtocolError(f"topic {event.topic!r} is not a valid ROS name")
        if not isinstance(event, (TopicMessage, Keepalive, ServiceRequest, ServiceResponse, Handshake)):
            command, params = command_params(event)
            try:
                _PARSERS[self.our_role][command].parse(command, params)
            except ProtocolError as error:
                raise LocalProtocolError(str(error)) from None
        return encode(event)
