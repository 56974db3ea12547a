"""ROS message and service types as the endpoint handles them: raw classes that carry a real type's name, md5sum
and definition (so rospy negotiates connections exactly as for the generated class) but serialize the bytes they
hold and deserialize by keeping them (`_has_header = False` keeps rospy from rewriting `header.seq`); the registry
that finds or builds them, and checks that a payload is one message of its type. No rospy: genpy only.
"""

from __future__ import annotations

import importlib
import os
import threading
from typing import Any, Callable

import genpy

from bridge.errors import BridgeError
from bridge.protocol.layout import Layout, LayoutError
from bridge.ros.definitions import (
    DefinitionError,
    RosPackages,
    message_class_from_files,
    message_class_from_text,
    service_class_from_files,
    split_type_name,
)

__all__ = ["RosError", "RawMessage", "TypeRegistry"]


class RosError(BridgeError, RuntimeError):
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
    try:
        return split_type_name(message_name)
    except DefinitionError as error:
        raise RosError(str(error)) from None


def _import_generated(message_name: str, kind: str, packages: RosPackages) -> Any:
    """The generated class of a message (kind "msg") or service ("srv"): the package's Python module, else one built
    from the definition files on ROS_PACKAGE_PATH (bridge.ros.definitions). Only a ROS package's own generated module is
    ever imported (see RosPackages). RosError says what to build or source."""
    package, type_name = _split_name(message_name)
    what = "message" if kind == "msg" else "service"
    if packages.has_generated(package, kind, type_name):
        try:
            return getattr(importlib.import_module(f"{package}.{kind}"), type_name)
        except (ImportError, AttributeError):
            pass
    elif not packages.exists(package):
        raise RosError(
            f"unknown {what} type {message_name!r}: {package!r} is not a ROS package (no generated Python "
            f"{package}/{kind}/_{type_name}.py, and not on ROS_PACKAGE_PATH: "
            f"{os.environ.get('ROS_PACKAGE_PATH') or 'not set'}); nothing was imported"
        )
    try:
        if kind == "msg":
            return message_class_from_files(message_name)
        return service_class_from_files(message_name)
    except DefinitionError as error:
        raise RosError(
            f"unknown {what} type {message_name!r}: no Python module {package}.{kind} has it (build the package, "
            f"and source its workspace's devel/setup.bash where the endpoint runs), and {error}"
        ) from None


class TypeRegistry:
    """Resolves 'pkg/Type' names to the generated classes and builds (cached) raw classes for them."""

    def __init__(self) -> None:
        self._lock = threading.Lock()  # held only to read and fill the caches, never while a type is looked up
        self._packages = RosPackages()
        self._raw_messages: dict[str, type[RawMessage]] = {}
        # service classes (genpy's and ours) are plain classes whose attributes genpy sets: typed Any
        self._raw_services: dict[str, Any] = {}
        self._generated: dict[str, type[genpy.Message]] = {}
        self._generated_services: dict[str, Any] = {}
        # 'pkg/Type' or 'pkg/Service request|response'; read without the lock: entries are only ever added
        self._layouts: dict[str, Layout] = {}

    def message_class(self, message_name: str) -> type[genpy.Message]:
        return self._imported(self._generated, message_name, "msg")

    def learn(self, message_name: str, full_text: str) -> None:
        """Take `message_name`'s class from its full definition (e.g. a publisher's connection header)."""
        try:
            cls = message_class_from_text(message_name, full_text)
        except DefinitionError as error:
            raise RosError(str(error)) from None
        with self._lock:
            self._generated.setdefault(message_name, cls)

    def raw_message_class(self, message_name: str) -> type[RawMessage]:
        generated = self.message_class(message_name)
        with self._lock:
            raw = self._raw_messages.get(message_name)
            if raw is None:
                raw = _raw_class_like(generated)
                self._raw_messages[message_name] = raw
            return raw

    def _generated_service(self, service_type: str) -> Any:
        return self._imported(self._generated_services, service_type, "srv")

    def _imported(self, cache: dict[str, Any], name: str, kind: str) -> Any:
        cls = cache.get(name)  # entries are only ever added
        if cls is not None:
            return cls
        # Looked up outside the lock: a look-up may take a while (files, genmsg), and other clients' types must
        # not wait for it. Two clients looking up one type at once both do; the first result is kept.
        cls = _import_generated(name, kind, self._packages)
        with self._lock:
            return cache.setdefault(name, cls)

    def raw_service_class(self, service_type: str) -> Any:
        generated = self._generated_service(service_type)
        with self._lock:
            raw = self._raw_services.get(service_type)
            if raw is not None:
                return raw
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
            self._raw_services[service_type] = raw
            return raw

    def validate(self, message_name: str, payload: bytes) -> None:
        """Prove the bytes are exactly one `message_name` (no truncation, no trailing bytes); RosError says why
        not. Walks the length prefixes only (bridge.protocol.layout), ~1 µs for a JointState instead of ~4 µs for a
        genpy deserialize, which would also need a bounds-checking wrapper (~11 µs) to catch truncated strings."""
        layout = self._layouts.get(message_name)
        if layout is None:
            layout = self._layout(message_name, lambda: self.message_class(message_name))
        self._check(layout, message_name, payload)

    def validate_service(self, service_type: str, part: str, payload: bytes) -> None:
        """`validate` for one part ("request" or "response") of a `service_type` call."""
        key = f"{service_type} {part}"
        layout = self._layouts.get(key)
        if layout is None:
            generated = self._generated_service(service_type)
            layout = self._layout(key, lambda: getattr(generated, f"_{part}_class"))
        self._check(layout, key, payload)

    @staticmethod
    def _check(layout: Layout, what: str, payload: bytes) -> None:
        try:
            layout.check(payload)
        except LayoutError as error:
            raise RosError(f"payload of {len(payload)} bytes is not a valid {what}: {error}") from None

    def _layout(self, key: str, message_class: Callable[[], type[genpy.Message]]) -> Layout:
        cls = message_class()
        try:
            layout = Layout(cls, self.message_class)
        except (LayoutError, ValueError) as error:
            raise RosError(f"cannot validate {key}: {error}") from None
        with self._lock:
            return self._layouts.setdefault(key, layout)


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
