"""The only module of `bridge` that touches rospy: raw-bytes topics and services on a ROS 1 graph.

Messages cross the endpoint as the bytes they arrived in. A raw class carries the real type's name, md5sum and
definition (so rospy negotiates connections exactly as for the generated class) but serializes stored bytes and
deserializes by keeping them; `_has_header = False` keeps rospy from rewriting `header.seq`.
"""
from __future__ import annotations

import importlib
import logging
import threading
from collections.abc import Callable
from typing import Any

import genpy
import rosgraph
import rospy

from bridge.layout import Layout, LayoutError

log = logging.getLogger(__name__)


class RosError(RuntimeError):
    """A ROS-side failure the client should hear about (unknown type, service call failed, ...)."""


class RawMessage(genpy.Message):
    """Base of the per-type raw classes; `_buff` holds one serialized message."""

    __slots__ = ("_buff",)
    _type = "*"
    _md5sum = "*"
    _full_text = ""
    _has_header = False
    _slot_types: list[str] = []

    def __init__(self, buff: bytes = b"") -> None:  # noqa: D107 - genpy's positional-args init is not wanted
        self._buff = buff

    def serialize(self, buff: Any) -> None:
        buff.write(self._buff)

    def deserialize(self, data: bytes) -> RawMessage:
        self._buff = bytes(data)
        return self


def _split_name(message_name: str) -> tuple[str, str]:
    package, _, type_name = message_name.partition("/")
    if not package or not type_name or "/" in type_name:
        raise RosError(f"type name {message_name!r} is not of the form 'package/Type'")
    return package, type_name


def _import_generated(message_name: str, kind: str) -> Any:
    package, type_name = _split_name(message_name)
    try:
        module = importlib.import_module(f"{package}.{kind}")
        return getattr(module, type_name)
    except (ImportError, AttributeError):
        raise RosError(f"unknown {'message' if kind == 'msg' else 'service'} type {message_name!r}") from None


class TypeRegistry:
    """Resolves 'pkg/Type' names to the generated classes and builds (cached) raw classes for them."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._raw_messages: dict[str, type[RawMessage]] = {}
        self._raw_services: dict[str, type] = {}
        self._generated: dict[str, type[genpy.Message]] = {}
        self._layouts: dict[str, Layout] = {}  # read without the lock: entries are only ever added

    def message_class(self, message_name: str) -> type[genpy.Message]:
        with self._lock:
            cls = self._generated.get(message_name)
            if cls is None:
                cls = _import_generated(message_name, "msg")
                self._generated[message_name] = cls
            return cls

    def raw_message_class(self, message_name: str) -> type[RawMessage]:
        generated = self.message_class(message_name)
        with self._lock:
            raw = self._raw_messages.get(message_name)
            if raw is None:
                raw = _raw_class_like(generated)
                self._raw_messages[message_name] = raw
            return raw

    def raw_service_class(self, service_name: str) -> type:
        with self._lock:
            raw = self._raw_services.get(service_name)
            if raw is not None:
                return raw
            generated = _import_generated(service_name, "srv")
            raw = type(
                f"Raw{generated.__name__}",
                (),
                {
                    "_type": generated._type,
                    "_md5sum": generated._md5sum,
                    "_request_class": _raw_class_like(generated._request_class),
                    "_response_class": _raw_class_like(generated._response_class),
                },
            )
            self._raw_services[service_name] = raw
            return raw

    def validate(self, message_name: str, payload: bytes) -> None:
        """Prove the bytes are exactly one `message_name` (no truncation, no trailing bytes); RosError says why
        not. Walks the length prefixes only (bridge.layout), ~1 µs for a JointState instead of ~4 µs for a genpy
        deserialize, which would also need a bounds-checking wrapper (~11 µs) to catch truncated strings."""
        layout = self._layouts.get(message_name)
        if layout is None:
            layout = self._layout(message_name)
        try:
            layout.check(payload)
        except LayoutError as error:
            raise RosError(f"payload of {len(payload)} bytes is not a valid {message_name}: {error}") from None

    def _layout(self, message_name: str) -> Layout:
        cls = self.message_class(message_name)
        try:
            layout = Layout(cls, self.message_class)
        except (LayoutError, ValueError) as error:
            raise RosError(f"cannot validate {message_name}: {error}") from None
        with self._lock:
            return self._layouts.setdefault(message_name, layout)


def _raw_class_like(generated: type[genpy.Message]) -> type[RawMessage]:
    return type(
        f"Raw{generated.__name__}",
        (RawMessage,),
        {
            "__slots__": (),
            "_type": generated._type,
            "_md5sum": generated._md5sum,
            "_full_text": generated._full_text,
            "_has_header": False,
        },
    )


MessageCallback = Callable[[str, bytes], None]
ServiceHandler = Callable[[bytes], bytes]


class RosGraph:
    """The endpoint's node on the ROS graph. Thread-safe; every rospy object is created and destroyed here."""

    def __init__(self, types: TypeRegistry | None = None) -> None:
        self.types = types or TypeRegistry()
        self._lock = threading.Lock()

    # --- node lifecycle -----------------------------------------------------------------------------------------
    @staticmethod
    def init_node(name: str) -> None:
        # disable_signals: the endpoint installs its own SIGINT/SIGTERM handling and shuts rospy down itself.
        rospy.init_node(name, anonymous=False, disable_signals=True)

    @staticmethod
    def get_param(name: str, default: Any) -> Any:
        return rospy.get_param(name, default)

    @staticmethod
    def set_param(name: str, value: Any) -> None:
        rospy.set_param(name, value)

    @staticmethod
    def shutdown(reason: str) -> None:
        rospy.signal_shutdown(reason)

    @staticmethod
    def is_shutdown() -> bool:
        return rospy.is_shutdown()

    @staticmethod
    def resolve(name: str) -> str:
        return rospy.resolve_name(name)

    # --- topics -----------------------------------------------------------------------------------------------
    def make_publisher(self, topic: str, message_name: str, queue_size: int, latch: bool) -> RawPublisher:
        raw = self.types.raw_message_class(message_name)
        # queue_size 0 would mean an unbounded rospy queue; keep at least one slot.
        publisher = rospy.Publisher(topic, raw, queue_size=max(queue_size, 1), latch=latch)
        return RawPublisher(publisher, raw, message_name)

    def make_subscriber(self, topic: str, message_name: str, callback: MessageCallback) -> Any:
        raw = self.types.raw_message_class(message_name)
        # tcp_nodelay: a 1 kHz stream must not wait for Nagle; buff_size large enough for big messages.
        return rospy.Subscriber(
            topic, raw, lambda msg: callback(topic, msg._buff), tcp_nodelay=True, buff_size=1 << 20
        )

    def topic_types(self) -> tuple[list[str], list[str]]:
        """All topics the master knows (published or subscribed) and their types, as parallel lists."""
        master = rosgraph.Master(rospy.get_name())
        pairs = sorted(master.getTopicTypes())
        return [name for name, _ in pairs], [type_name for _, type_name in pairs]

    # --- services ---------------------------------------------------------------------------------------------
    def make_service_proxy(self, service: str, service_name: str) -> RawServiceProxy:
        raw = self.types.raw_service_class(service_name)
        return RawServiceProxy(rospy.ServiceProxy(service, raw), raw, service)

    def make_service(self, service: str, service_name: str, handler: ServiceHandler) -> Any:
        raw = self.types.raw_service_class(service_name)
        response_class = raw._response_class

        def handle(request: RawMessage) -> RawMessage:
            return response_class(handler(request._buff))

        return rospy.Service(service, raw, handle)


class RawPublisher:
    def __init__(self, publisher: Any, raw_class: type[RawMessage], message_name: str) -> None:
        self._publisher = publisher
        self._raw_class = raw_class
        self.message_name = message_name

    def publish(self, payload: bytes) -> None:
        self._publisher.publish(self._raw_class(payload))

    def unregister(self) -> None:
        self._publisher.unregister()


class RawServiceProxy:
    def __init__(self, proxy: Any, raw_class: type, service: str) -> None:
        self._proxy = proxy
        self._request_class = raw_class._request_class
        self.service = service

    def call(self, request: bytes, timeout: float) -> bytes:
        try:
            self._proxy.wait_for_service(timeout=timeout)
        except rospy.ROSException:
            raise RosError(f"service {self.service} is not available (waited {timeout:g} s)") from None
        try:
            response = self._proxy.call(self._request_class(request))
        except rospy.ServiceException as error:
            raise RosError(f"service {self.service} failed: {error}") from None
        except (rospy.ROSException, OSError) as error:
            raise RosError(f"service {self.service} could not be called: {error}") from None
        return response._buff

    def close(self) -> None:
        self._proxy.close()
