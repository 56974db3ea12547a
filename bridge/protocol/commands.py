"""The protocol's system commands (destinations starting "__", each one JSON object) as typed events and back, and
the bytes of every event (`encode`), whoever sends it. Sans I/O: bridge.protocol's Conversation uses these tables
to parse what the peer says and to check what it says itself; the JSON a peer sends is checked for depth before it
is decoded."""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from typing import Any, Callable, Dict, Type, Union

from bridge.protocol.events import (
    PROTOCOL_VERSION,
    REMOVE_KINDS,
    ROS_DISTRO_PROTOCOL,
    Auth,
    Error,
    Event,
    Handshake,
    Keepalive,
    LocalProtocolError,
    Log,
    Ping,
    PingResponse,
    ProtocolError,
    Publish,
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
from bridge.protocol.framing import KEEPALIVE_FRAME, encode_frame, encode_syscommand
from bridge.protocol.names import graph_name_problem, type_name_problem

__all__ = [
    "CLIENT_COMMANDS",
    "MAX_JSON_NESTING",
    "SENT_BY_CLIENT",
    "SENT_BY_ENDPOINT",
    "SERVICE_HEADER",
    "SERVICE_HEADERS",
    "ServiceEvent",
    "command_params",
    "encode",
    "handshake",
    "json_object",
]

# --- system commands: JSON <-> events ----------------------------------------------------------------------------

_Params = Dict[str, Any]
_Fields = Dict[str, type]


@dataclass(frozen=True)
class _Command:
    """One system command's JSON: the fields it must have, those it may have (each with its type), and how its
    checked fields make the event. Fields outside both are not this protocol's: ignored, and reported once."""

    required: _Fields
    optional: _Fields
    build: Callable[[str, _Params], Event]

    def parse(self, command: str, params: _Params) -> Event:
        for name in self.required:
            if name not in params:
                raise ProtocolError(f"{command}: missing field {name!r}")
        for name, expected in (*self.required.items(), *self.optional.items()):
            if name in params:
                _check_type(command, name, params[name], expected)
        return self.build(command, params)

    def unknown_fields(self, params: _Params) -> tuple[str, ...]:
        return tuple(sorted(name for name in params if name not in self.required and name not in self.optional))


def _check_type(command: str, name: str, value: Any, expected: type) -> None:
    # bool is a subclass of int in Python; a srv_id of `true` is still wrong.
    if expected is int and (isinstance(value, bool) or not isinstance(value, int)):
        raise ProtocolError(f"{command}: field {name!r} must be an integer, got {value!r}")
    if expected is float and not isinstance(value, bool) and isinstance(value, int):
        return  # JSON writes 3.0 as 3
    if not isinstance(value, expected):
        raise ProtocolError(f"{command}: field {name!r} must be a {expected.__name__}, got {value!r}")


def _check_name(command: str, field: str, name: str) -> str:
    problem = graph_name_problem(name)
    if problem is not None:
        raise ProtocolError(f"{command}: field {field!r} is not a valid ROS name: {name!r} {problem}")
    return name


def _check_message_name(command: str, message_name: str) -> str:
    problem = type_name_problem(message_name)
    if problem is not None:
        raise ProtocolError(f"{command}: field 'message_name' is not a ROS type name: {message_name!r} {problem}")
    return message_name


def _not_negative(command: str, field: str, value: int) -> int:
    if value < 0:
        raise ProtocolError(f"{command}: field {field!r} must be >= 0, got {value}")
    return value


def _topic_and_type(command: str, params: _Params) -> tuple[str, str]:
    return _check_name(command, "topic", params["topic"]), _check_message_name(command, params["message_name"])


def _subscribe(command: str, params: _Params) -> Event:
    queue_size = params.get("queue_size")
    return Subscribe(
        *_topic_and_type(command, params),
        None if queue_size is None else _not_negative(command, "queue_size", queue_size),
    )


def _publish(command: str, params: _Params) -> Event:
    return Publish(
        *_topic_and_type(command, params),
        _not_negative(command, "queue_size", params.get("queue_size", 10)),
        params.get("latch", False),
    )


def _topic_list(command: str, params: _Params) -> Event:
    topics, types = params["topics"], params["types"]
    if len(topics) != len(types) or not all(isinstance(name, str) for name in (*topics, *types)):
        raise ProtocolError(f"{command}: 'topics' and 'types' must be lists of names of the same length")
    return TopicList(tuple(topics), tuple(types))


def _handshake(command: str, params: _Params) -> Event:
    try:
        metadata = _json_value(command, params.get("metadata", "{}").encode("utf-8"))
    except ProtocolError:
        metadata = None
    if not isinstance(metadata, dict):
        raise ProtocolError(f"{command}: field 'metadata' must hold a JSON object, got {params['metadata']!r}")
    return Handshake(params["version"], metadata)


_TOPIC: _Fields = {"topic": str}
_REGISTRATION: _Fields = {"topic": str, "message_name": str}
_TEXT: _Fields = {"text": str}
_REQUEST_TIME: _Fields = {"request_time": str}
_SRV_ID: _Fields = {"srv_id": int}

# What each role may say: command -> its JSON. A service header (`SERVICE_HEADERS`) is paired with its body.
SENT_BY_CLIENT: dict[str, _Command] = {
    "__subscribe": _Command(_REGISTRATION, {"queue_size": int}, _subscribe),
    "__publish": _Command(_REGISTRATION, {"queue_size": int, "latch": bool}, _publish),
    "__ros_service": _Command(_REGISTRATION, {}, lambda command, params: RosService(*_topic_and_type(command, params))),
    "__unity_service": _Command(
        _REGISTRATION, {}, lambda command, params: UnityService(*_topic_and_type(command, params))
    ),
    "__topic_list": _Command({}, {}, lambda command, params: TopicListQuery()),
    "__auth": _Command({"token": str}, {}, lambda command, params: Auth(params["token"])),
    "__ping": _Command(
        _REQUEST_TIME,
        {"round_trip": float},
        lambda command, params: Ping(params["request_time"], params.get("round_trip")),
    ),
    **{
        f"__remove_{kind}": _Command(
            _TOPIC,
            {},
            lambda command, params: Remove(command[len("__remove_") :], _check_name(command, "topic", params["topic"])),
        )
        for kind in REMOVE_KINDS
    },
}
SENT_BY_ENDPOINT: dict[str, _Command] = {
    "__handshake": _Command({"version": str}, {"metadata": str}, _handshake),
    "__topic_list": _Command({"topics": list, "types": list}, {}, _topic_list),
    "__ping_response": _Command(
        _REQUEST_TIME,
        {"ros_time": float},
        lambda command, params: PingResponse(params["request_time"], params.get("ros_time")),
    ),
    "__log": _Command(_TEXT, {}, lambda command, params: Log(params["text"])),
    "__warn": _Command(_TEXT, {}, lambda command, params: Warn(params["text"])),
    "__error": _Command(_TEXT, {"srv_id": int}, lambda command, params: Error(params["text"], params.get("srv_id"))),
}
ServiceEvent = Union[Type[ServiceRequest], Type[ServiceResponse]]
SERVICE_HEADERS: dict[str, ServiceEvent] = {"__request": ServiceRequest, "__response": ServiceResponse}
SERVICE_HEADER = _Command(_SRV_ID, {}, lambda command, params: Event())  # the event comes with the body
CLIENT_COMMANDS = frozenset((*SENT_BY_CLIENT, *SERVICE_HEADERS))


def command_params(event: Event) -> tuple[str, _Params]:
    """The system command that carries `event`, and its JSON fields in the order Unity writes them."""
    if isinstance(event, Subscribe):
        return "__subscribe", _given(
            {"topic": event.topic, "message_name": event.message_name}, queue_size=event.queue_size
        )
    if isinstance(event, Publish):
        return "__publish", {
            "topic": event.topic,
            "message_name": event.message_name,
            "queue_size": event.queue_size,
            "latch": event.latch,
        }
    if isinstance(event, RosService):
        return "__ros_service", {"topic": event.topic, "message_name": event.message_name}
    if isinstance(event, UnityService):
        return "__unity_service", {"topic": event.topic, "message_name": event.message_name}
    if isinstance(event, Remove):
        return f"__remove_{event.kind}", {"topic": event.topic}
    if isinstance(event, TopicListQuery):
        return "__topic_list", {}
    if isinstance(event, TopicList):
        return "__topic_list", {"topics": list(event.topics), "types": list(event.types)}
    if isinstance(event, Auth):
        return "__auth", {"token": event.token}
    if isinstance(event, Ping):
        return "__ping", _given({"request_time": event.request_time}, round_trip=event.round_trip)
    if isinstance(event, PingResponse):
        return "__ping_response", _given({"request_time": event.request_time}, ros_time=event.ros_time)
    if isinstance(event, Log):
        return "__log", {"text": event.text}
    if isinstance(event, Warn):
        return "__warn", {"text": event.text}
    if isinstance(event, Error):
        return "__error", _given({"text": event.text}, srv_id=event.srv_id)
    raise LocalProtocolError(f"{type(event).__name__} is not a system command")


def _given(params: _Params, **optional: Any) -> _Params:
    """`params` and the optional fields that have a value (an absent field is left out, not sent as null)."""
    params.update((name, value) for name, value in optional.items() if value is not None)
    return params


def handshake() -> bytes:
    """The endpoint's first frame, byte for byte what the v0.7.0 endpoint sends."""
    return encode(Handshake(PROTOCOL_VERSION, {"protocol": ROS_DISTRO_PROTOCOL}))


def encode(event: Event) -> bytes:
    """The bytes of any event, whoever sends it; a service event is its header and body back to back, so nothing
    can come between them on the wire. Use Conversation.send to also check that your role may send it."""
    if type(event) is TopicMessage:
        return encode_frame(event.topic, event.payload)
    if isinstance(event, (ServiceRequest, ServiceResponse)):
        header = "__request" if isinstance(event, ServiceRequest) else "__response"
        return encode_syscommand(header, {"srv_id": event.srv_id}) + encode_frame(event.service, event.payload)
    if isinstance(event, Keepalive):
        return KEEPALIVE_FRAME
    if isinstance(event, Handshake):
        # As the v0.7.0 endpoint writes it: json.dumps with its default ", " and ": " separators.
        body = json.dumps({"version": event.version, "metadata": json.dumps(event.metadata)})
        return encode_frame("__handshake", body.encode("utf-8"))
    command, params = command_params(event)
    return encode_syscommand(command, params)


# Commands nest three levels at most. Deeper input is refused before json.loads sees it: relying on its
# RecursionError is not safe on Python 3.8, which aborts the whole process ("Cannot recover from stack overflow")
# when the decoder recurses while a RecursionError caught earlier on the same stack (in a garbage collector's
# finalizer, say) still counts.
MAX_JSON_NESTING = 32
_JSON_ESCAPE = re.compile(rb"\\.", re.DOTALL)
_JSON_STRING = re.compile(rb'"[^"]*"')  # with escapes gone and every quote matched, linear
_NOT_A_BRACKET = bytes(byte for byte in range(256) if byte not in b"[]{}")
_BRACKETS_AS_ONE_KIND = bytes.maketrans(b"{}", b"[]")


def _json_nesting_exceeds(payload: bytes, limit: int) -> bool:
    """True when payload's arrays and objects nest deeper than limit; False bounds json.loads's depth by 2 * limit.

    Works on the brackets outside strings, all of one kind, at the speed of bytes methods: each pass removes every
    innermost pair, so a pair left after limit passes sits deeper than limit. No pass removes brackets that never
    close, which the decoder also descends into before it finds the error.
    """
    if payload.count(b"[") + payload.count(b"{") <= limit:  # the usual command needs no scan
        return False
    unescaped = _JSON_ESCAPE.sub(b"", payload)
    if unescaped.count(b'"') % 2:  # the decoder stops at a string that never ends: so does the scan
        unescaped = unescaped[: unescaped.rindex(b'"')]
    outside_strings = _JSON_STRING.sub(b"", unescaped)
    brackets = outside_strings.translate(_BRACKETS_AS_ONE_KIND, _NOT_A_BRACKET)
    too_deep = b"[" * (limit + 1)
    for _ in range(limit):
        if too_deep in brackets:  # spares the passes that would peel such a run one pair at a time
            return True
        innermost_removed = brackets.replace(b"[]", b"")
        if innermost_removed == brackets:
            break
        brackets = innermost_removed
    return b"[]" in brackets or brackets.count(b"[") > limit


def _json_value(command: str, text: bytes) -> Any:
    if _json_nesting_exceeds(text, MAX_JSON_NESTING):
        raise ProtocolError(f"{command}: JSON nested more than {MAX_JSON_NESTING} levels deep")
    try:
        return json.loads(text.decode("utf-8"))
    except UnicodeDecodeError:
        raise ProtocolError(f"{command}: payload is not valid UTF-8") from None
    except json.JSONDecodeError as error:
        raise ProtocolError(f"{command}: malformed JSON ({error.msg} at position {error.pos})") from None


def json_object(command: str, payload: bytes) -> _Params:
    params = _json_value(command, payload) if payload else {}
    if not isinstance(params, dict):
        raise ProtocolError(f"{command}: payload must be a JSON object, got {type(params).__name__}")
    return params
