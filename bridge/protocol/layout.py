"""Structural validation of ROS 1 serialized messages without deserializing them.

The endpoint forwards a client's bytes unchanged, so all it must prove is that they *are* one message of the
declared type: every length prefix fits inside the payload and the message ends exactly at the payload's end
(no truncation, no trailing bytes). Deserializing with genpy proves less (its generated code slices strings past
the end without complaint) and costs more (it builds every field). A `Layout` walks only the length prefixes:
runs of fixed-size fields collapse into one skip, and arrays of fixed-size elements into one multiplication.

What genpy would check beyond this, it does not: it replaces invalid UTF-8 and accepts any bool byte. So a
payload passes here exactly when it is a well-formed message of the type. Imports neither socket nor rospy.
"""

from __future__ import annotations

import struct
from typing import Any, Callable

from bridge.errors import BridgeError

__all__ = ["Step", "ClassResolver", "LayoutError", "Layout"]

_U32 = struct.Struct("<I")
_read_u32 = _U32.unpack_from
_FIXED_SIZES = {
    "bool": 1,
    "int8": 1,
    "uint8": 1,
    "byte": 1,
    "char": 1,
    "int16": 2,
    "uint16": 2,
    "int32": 4,
    "uint32": 4,
    "int64": 8,
    "uint64": 8,
    "float32": 4,
    "float64": 8,
    "time": 8,
    "duration": 8,
}

# One step of a walk: (payload, offset) -> offset after the field(s). Reading a length prefix past the end raises
# struct.error; skipping past the end just yields an offset > len(payload), caught by the final comparison.
Step = Callable[[bytes, int], int]
ClassResolver = Callable[[str], Any]  # 'pkg/Type' -> generated class with `_slot_types`


class LayoutError(BridgeError, ValueError):
    """The payload is not one well-formed message of the type; the text says where it breaks."""


class Layout:
    """The length-prefix structure of one message type, compiled once from its generated class."""

    def __init__(self, message_class: Any, resolve: ClassResolver) -> None:
        self.type_name: str = message_class._type
        self.fixed_size, self._steps = _compile(message_class, resolve, depth=0)

    def check(self, payload: bytes) -> None:
        """Raise LayoutError unless `payload` is exactly one message of this type."""
        try:
            end = self.fixed_size
            for step in self._steps:
                end = step(payload, end)
        except struct.error:
            raise LayoutError(f"truncated: a length prefix lies past the end of the {len(payload)} bytes") from None
        if end > len(payload):
            raise LayoutError(f"truncated: the message needs at least {end} bytes")
        if end < len(payload):
            raise LayoutError(f"{len(payload) - end} trailing byte(s) after the message")


def _compile(message_class: Any, resolve: ClassResolver, depth: int) -> tuple[int, list[Step]]:
    """(bytes of the fields before the first variable-size one, steps for the rest).

    Runs of fixed-size fields become one skip, so JointState is 5 steps: frame_id, name[], 3 x float64[].
    """
    if depth > 32:
        raise LayoutError(f"{message_class._type}: message types nested more than 32 deep")
    leading = 0  # fixed bytes before the first variable-size field
    steps: list[Step] = []
    pending = 0  # fixed bytes not yet attached to a step

    def flush_into(step: Step) -> None:
        nonlocal pending, leading
        if not steps:
            leading = pending
        elif pending:
            steps.append(_skip(pending))
        pending = 0
        steps.append(step)

    for slot_type in message_class._slot_types:
        base, is_array, length = _parse(slot_type)
        element_fixed, element_steps = _element(base, resolve, depth)
        if not is_array:
            if not element_steps:
                pending += element_fixed
                continue
            # a nested variable-size message inline: its leading bytes, then its own steps
            pending += element_fixed
            for step in element_steps:
                flush_into(step)
            continue
        if not element_steps:  # array of fixed-size elements
            if length is not None:
                pending += element_fixed * length
            else:
                flush_into(_counted_fixed(element_fixed))
            continue
        if element_steps == [_string] and not element_fixed:
            flush_into(_counted_strings(length))  # string[] (joint names): the commonest array, walked inline
        else:
            flush_into(_counted_variable(element_fixed, element_steps, length))
    if not steps:
        return pending, []
    if pending:  # fixed bytes after the last variable-size field
        steps.append(_skip(pending))
    return leading, steps


def _parse(slot_type: str) -> tuple[str, bool, int | None]:
    if not slot_type.endswith("]"):
        return slot_type, False, None
    base, _, rest = slot_type.partition("[")
    size = rest[:-1]
    return base, True, int(size) if size else None


def _element(base: str, resolve: ClassResolver, depth: int) -> tuple[int, list[Step]]:
    """Layout of one element: (fixed bytes before the first variable field, steps)."""
    if base in _FIXED_SIZES:
        return _FIXED_SIZES[base], []
    if base == "string":
        return 0, [_string]
    return _compile(resolve(base), resolve, depth + 1)


def _skip(size: int) -> Step:
    def step(payload: bytes, offset: int) -> int:
        return offset + size

    return step


def _string(payload: bytes, offset: int) -> int:
    return offset + 4 + _read_u32(payload, offset)[0]


def _counted_strings(length: int | None) -> Step:
    """`string[]` or `string[N]`: `_counted_variable` with the string step inlined (a call less per string)."""

    def step(payload: bytes, offset: int) -> int:
        if length is None:
            count = _read_u32(payload, offset)[0]
            offset += 4
        else:
            count = length
        for _ in range(count):
            offset += 4 + _read_u32(payload, offset)[0]
        return offset

    return step


def _counted_fixed(element_size: int) -> Step:
    """`T[]` with fixed-size T: u32 count, then count * size bytes."""

    def step(payload: bytes, offset: int) -> int:
        return offset + 4 + element_size * _read_u32(payload, offset)[0]

    return step


def _counted_variable(element_fixed: int, element_steps: list[Step], length: int | None) -> Step:
    """`T[]` or `T[N]` with variable-size T: walk every element. Each element holds at least one 4-byte length
    prefix, so a huge count fails after at most len(payload) / 4 iterations."""

    def step(payload: bytes, offset: int) -> int:
        if length is None:
            count = _read_u32(payload, offset)[0]
            offset += 4
        else:
            count = length
        for _ in range(count):
            offset += element_fixed
            for element_step in element_steps:
                offset = element_step(payload, offset)
        return offset

    return step
