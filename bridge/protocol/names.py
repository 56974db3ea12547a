"""ROS graph names and type names, checked by ROS's rules before anything reaches the master or an import.

A graph name (topic, service) starts with a letter, '/' or '~' and goes on with ASCII letters, digits, '_' and '/',
never '//' (rosgraph.names.is_legal_name, restricted to ASCII as roscpp's check is). A type name is
'package/Type', both parts a letter followed by letters, digits and '_' (genmsg's rule for package and message
names). The master's XML-RPC and rospy retry forever on names they cannot carry, so nothing unchecked goes there.
Pure: no I/O.
"""

from __future__ import annotations

__all__ = ["graph_name_problem", "type_name_problem"]

_LETTERS = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ")
_WORD = _LETTERS | frozenset("0123456789_")
_GRAPH_FIRST = _LETTERS | frozenset("/~")
_GRAPH_REST = _WORD | frozenset("/")


def _shown(character: str) -> str:
    return f"{character!r} (U+{ord(character):04X})"


def graph_name_problem(name: str, max_bytes: int | None = None) -> str | None:
    """Why `name` is not a legal ROS graph name (of at most `max_bytes` UTF-8 bytes, if given); None when it is."""
    if not name:
        return "is empty"
    if name[0] not in _GRAPH_FIRST:
        return f"starts with {_shown(name[0])}; a ROS name starts with a letter, '/' or '~'"
    for position, character in enumerate(name[1:], start=1):
        if character not in _GRAPH_REST:
            return (
                f"has {_shown(character)} at position {position}; a ROS name holds only ASCII letters, digits, "
                "'_' and '/'"
            )
    if "//" in name:
        return f"has '//' at position {name.index('//')}"
    if max_bytes is not None and len(name) > max_bytes:  # ASCII from here: one byte per character
        return f"is {len(name)} bytes long, more than the {max_bytes} a destination may have"
    return None


def type_name_problem(name: str) -> str | None:
    """Why `name` is not of the form 'package/Type' by ROS's naming rules; None when it is."""
    package, slash, type_name = name.partition("/")
    if not slash or not package or not type_name:
        return "is not of the form 'package/Type'"
    for part in (package, type_name):
        if part[0] not in _LETTERS:
            return f"has {part!r}, which does not start with a letter"
        for character in part:
            if character not in _WORD:
                return f"has {_shown(character)}; package and type names hold only ASCII letters, digits and '_'"
    return None
