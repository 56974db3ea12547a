"""What the page's server says to the endpoint for a page's WebSocket, as bytes: the upgrade request it passes on,
and the `__auth` it sends first when the endpoint wants a token. Pure logic: no socket.

The browser never sees the endpoint's token: the page cannot send `__auth`, so the server does, in the page's
connection, before any of the page's own frames. The endpoint believes the browser's address in X-Forwarded-For
only from a trusted proxy that also shows the proxy secret the endpoint was given (X-Proxy-Secret); both come from
this server, never from the client, whatever the client wrote.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Iterable

__all__ = ["AUTH_TOKEN_ENV", "PROXY_SECRET_ENV", "auth_message", "upgrade_request"]

AUTH_TOKEN_ENV = "ROS_TCP_AUTH_TOKEN"  # the endpoint's --auth-token, for the server to authenticate the pages
PROXY_SECRET_ENV = "ROS_TCP_PROXY_SECRET"  # the endpoint's --proxy-secret, shown with X-Forwarded-For
# Headers the endpoint is told afresh, or not at all (the page's cookie holds this server's key, not the endpoint's)
_REPLACED_HEADERS = (b"origin", b"x-forwarded-for", b"forwarded", b"x-proxy-secret", b"cookie")
_U32 = struct.Struct("<I")
_BINARY_FINAL = 0x82  # FIN, opcode 2 (binary)
_MASKED = 0x80


def upgrade_request(
    method: bytes, path: bytes, headers: Iterable[tuple[bytes, bytes]], browser: str, proxy_secret: str | None
) -> bytes:
    """The WebSocket upgrade for the endpoint: the browser's request to `path` (its query, which held this
    server's key, left out), its headers in their own case, without its Origin (checked here), cookie or proxy
    headers, and with the browser's address as this server saw it and, when given, the proxy secret."""
    lines = [method + b" " + path + b" HTTP/1.1"]
    lines += [name + b": " + value for name, value in headers if name.lower() not in _REPLACED_HEADERS]
    lines.append(b"X-Forwarded-For: " + browser.encode("ascii"))
    if proxy_secret:
        lines.append(b"X-Proxy-Secret: " + proxy_secret.encode("latin-1"))
    return b"\r\n".join(lines) + b"\r\n\r\n"


def auth_message(token: str, mask: bytes) -> bytes:
    """The endpoint's `__auth` command with `token`, as one masked binary WebSocket message (a client's frames are
    masked, RFC 6455 5.3): the ROS-TCP frame (destination and JSON body, each after its u32 little-endian length)."""
    if len(mask) != 4:
        raise ValueError(f"a WebSocket mask is 4 bytes, not {len(mask)}")
    body = json.dumps({"token": token}, separators=(",", ":")).encode("utf-8")
    payload = _U32.pack(len(b"__auth")) + b"__auth" + _U32.pack(len(body)) + body
    size = len(payload)
    if size < 126:
        head = bytes([_BINARY_FINAL, _MASKED | size])
    elif size < 1 << 16:
        head = bytes([_BINARY_FINAL, _MASKED | 126]) + struct.pack("!H", size)
    else:
        head = bytes([_BINARY_FINAL, _MASKED | 127]) + struct.pack("!Q", size)
    return head + mask + bytes(byte ^ mask[index % 4] for index, byte in enumerate(payload))
