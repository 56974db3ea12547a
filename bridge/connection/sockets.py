"""Socket helpers shared by the endpoint's client side (bridge.connection.session), its ROS side
(bridge.ros.publisher) and the Python client (bridge.client)."""

from __future__ import annotations

import fcntl
import ipaddress
import math
import os
import select
import socket
import struct
import termios
import time
from collections.abc import Sequence

__all__ = [
    "unsent_bytes",
    "takes_whole",
    "send_now",
    "wait_writable",
    "tune_socket",
    "unpaced_on_loopback",
    "limit_unsent",
    "UnsentLimit",
    "send_to_all",
    "NOTSENT_LOWAT_BYTES",
    "BEHIND_BYTES",
]

# What limit_unsent leaves the kernel: 1.3 ms at 100 Mbit/s.
NOTSENT_LOWAT_BYTES = 16 * 1024
# A connection is behind when this much still waits in the kernel as its next large frame is written: the link is
# slower than the sender (100 Mbit/s Wi-Fi has taken ~400 KB of a 30 Hz camera's previous frame by then, a local
# client all of it).
BEHIND_BYTES = 256 * 1024
TCP_NOTSENT_LOWAT = getattr(socket, "TCP_NOTSENT_LOWAT", 25)  # Linux's number, for Pythons that do not name it
# Congestion controls that pace every connection (see unpaced_on_loopback), and what to use instead, in order of
# preference (reno is built into every Linux kernel and allowed to every user).
PACING_CONGESTION_CONTROLS = (b"bbr", b"bbr2", b"bbr3")
LOOPBACK_CONGESTION_CONTROLS = (b"cubic", b"reno")
_INT = struct.Struct("i")
_INT_ZERO = bytes(_INT.size)


def unsent_bytes(sock: socket.socket) -> int:
    """Bytes in the socket's send queue not yet acknowledged by the peer (Linux SIOCOUTQ); 0 if unknown."""
    try:
        return _INT.unpack(fcntl.ioctl(sock.fileno(), termios.TIOCOUTQ, _INT_ZERO))[0]
    except OSError:
        return 0


def unread_bytes(sock: socket.socket) -> int:
    """Bytes received by the kernel that the socket's reader has not taken yet (Linux FIONREAD); 0 if unknown."""
    try:
        return _INT.unpack(fcntl.ioctl(sock.fileno(), termios.FIONREAD, _INT_ZERO))[0]
    except OSError:
        return 0


def takes_whole(sock: socket.socket, size: int) -> bool:
    """A socket with nothing unacknowledged takes `size` bytes in one non-blocking write: they fit in half its send
    buffer (Linux doubles SO_SNDBUF for its bookkeeping, and autotunes it to a connection's traffic)."""
    try:
        return size <= sock.getsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF) // 2
    except OSError:
        return False


def send_now(sock: socket.socket, data: bytes | memoryview) -> int:
    """Write what the kernel takes at once and return how much that was; never waits.

    MSG_DONTWAIT alone is not enough: on a socket with a Python timeout, CPython waits for writability (up to the
    timeout) before sending. Such a socket's descriptor is non-blocking, so a plain write returns at once. rospy
    sets a process-wide default timeout of 60 s when it connects a subscriber, which every socket made after
    that inherits (rospy resets its own connections to blocking in their handshake; tune_socket does the same
    for the endpoint's clients), so no socket's mode is taken for granted here."""
    try:
        if sock.gettimeout() is None:
            return sock.send(data, socket.MSG_DONTWAIT)
        return os.write(sock.fileno(), data)
    except BlockingIOError:
        return 0


def wait_writable(sock: socket.socket, timeout_s: float) -> bool:
    """Until the socket takes more bytes (with limit_unsent: until less than half of NOTSENT_LOWAT_BYTES waits
    unsent), or fails, or `timeout_s` passed (False)."""
    poller = select.poll()
    poller.register(sock.fileno(), select.POLLOUT)
    return bool(poller.poll(timeout_s * 1000))


def tune_socket(sock: socket.socket, dead_peer_timeout_s: float) -> None:
    """A client connection: blocking mode, no Nagle, and a vanished peer noticed within `dead_peer_timeout_s`."""
    # Blocking whatever the process-wide default timeout (see send_now): the writer thread's sendall must wait for
    # a slow client as long as it takes (the per-client queue bounds memory), not give up after rospy's 60 s.
    sock.settimeout(None)
    # TCP_NODELAY: at 1 kHz, Nagle + delayed ACK would add 40 ms spikes.
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    unpaced_on_loopback(sock)
    # An idle peer is probed (keepalive: a third of the time idle, then probes filling the rest); one that does not
    # acknowledge what it is sent is given up after the whole time (TCP_USER_TIMEOUT; without it, Linux retries
    # for some 15 minutes). So is one whose receive window stays shut that long (Linux applies the user timeout to
    # window probes too): a client that takes nothing for that long cannot be served anyway.
    idle = max(1, int(dead_peer_timeout_s / 3))
    interval = max(1, int(dead_peer_timeout_s / 6))
    count = max(1, int((dead_peer_timeout_s - idle) / interval))
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
    for option, value in (
        ("TCP_KEEPIDLE", idle),
        ("TCP_KEEPINTVL", interval),
        ("TCP_KEEPCNT", count),
        ("TCP_USER_TIMEOUT", int(dead_peer_timeout_s * 1000)),
    ):
        if hasattr(socket, option):
            sock.setsockopt(socket.IPPROTO_TCP, getattr(socket, option), value)


def unpaced_on_loopback(sock: socket.socket) -> None:
    """A connection within this machine does not get a pacing congestion control (BBR, the default of some kernels).

    BBR paces what it sends at the bandwidth it has measured from the peer's acknowledgements. Within one machine
    there is no link to protect, and the "bandwidth" it measures is how promptly the receiving program reads: a
    pause of a game engine's or Python's reader (a frame, a garbage collection) makes it pace the next camera
    images at that rate for several round trips. Measured (1 MiB round trips at 30 Hz through the endpoint, BBR):
    stalls of 40-115 ms in most runs of 300, and a message dropped behind them; with cubic or reno, none in
    eight runs. Connections from other machines keep the system's choice. Nothing is done where the kernel does
    not say or allow it."""
    congestion = getattr(socket, "TCP_CONGESTION", None)
    if congestion is None:
        return
    try:
        if not _is_loopback(sock.getpeername()[0]):
            return
        if sock.getsockopt(socket.IPPROTO_TCP, congestion, 16).rstrip(b"\0") not in PACING_CONGESTION_CONTROLS:
            return
    except (OSError, ValueError, IndexError):
        return
    for name in LOOPBACK_CONGESTION_CONTROLS:
        try:
            sock.setsockopt(socket.IPPROTO_TCP, congestion, name)
            return
        except OSError:  # not built, or not allowed to this user (net.ipv4.tcp_allowed_congestion_control)
            continue


def _is_loopback(host: str) -> bool:
    address = ipaddress.ip_address(host.split("%", 1)[0])
    if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped is not None:
        address = address.ipv4_mapped
    return address.is_loopback


def limit_unsent(sock: socket.socket) -> None:
    """Let the kernel hold at most NOTSENT_LOWAT_BYTES not yet sent (TCP_NOTSENT_LOWAT), so that the sender, not a
    send buffer the kernel grows to megabytes, decides what goes next: on a slow link, nothing then waits behind
    seconds of older data. Meant for connections that carry large messages (camera images): for floods of small
    ones, the kernel's buffer is what absorbs a reader's hiccups (measured: without it, 12 % fewer of a 200k msg/s
    flood reached a client on loopback)."""
    try:
        sock.setsockopt(socket.IPPROTO_TCP, TCP_NOTSENT_LOWAT, NOTSENT_LOWAT_BYTES)
    except OSError:  # a kernel without it: the send buffer alone bounds what waits
        pass


class UnsentLimit:
    """limit_unsent for one connection, from the first large frame that finds it behind (BEHIND_BYTES unsent).

    A connection that keeps up never gets it: with TCP_NOTSENT_LOWAT the kernel wakes a writer for every 16 KiB,
    which cost a local client ~0.3 ms of each 1 MiB round trip; there the kernel's buffer is drained at once anyway.
    On a slow link the first frames find the kernel still holding the one before, and from then on the sender
    decides what goes next. Not thread-safe: call it where the socket's writes are serialised (or accept a rare
    second setsockopt, which is harmless)."""

    __slots__ = ("_sock", "limited")

    def __init__(self, sock: socket.socket) -> None:
        self._sock = sock
        self.limited = False

    def before_large_write(self) -> None:
        """Call before writing a large frame (an ioctl until the connection is limited, nothing after)."""
        if not self.limited and unsent_bytes(self._sock) >= BEHIND_BYTES:
            self.limited = True
            limit_unsent(self._sock)


def send_to_all(socks: Sequence[socket.socket], data: bytes, stall_s: float) -> dict[int, str]:
    """Write `data` whole to every socket; returns {index: why} for those that failed.

    Each socket first gets a non-blocking send, so healthy peers have the bytes at once whatever the others do.
    Peers that did not take everything are then waited for together: one that keeps taking bytes is waited for as
    long as it needs (the caller is slowed to its pace, as by a blocking sendall), one that takes nothing for
    `stall_s` has stopped reading and fails. A failed socket holds part of `data`: its stream is no longer whole,
    so the caller must close it.
    """
    failed: dict[int, str] = {}
    behind: dict[int, memoryview] = {}
    whole = memoryview(data)
    for index, sock in enumerate(socks):
        try:
            sent = send_now(sock, whole)
        except OSError as error:
            failed[index] = str(error)
            continue
        if sent < len(whole):
            behind[index] = whole[sent:]
    if behind:
        failed.update(_finish_sends(socks, behind, stall_s))
    return failed


def _finish_sends(socks: Sequence[socket.socket], behind: dict[int, memoryview], stall_s: float) -> dict[int, str]:
    """Keep writing the rest of `data` to the peers that are behind. Progress is the peer acknowledging bytes (the
    kernel's unacknowledged count falls) or taking more: writability alone is too coarse a sign, since the kernel
    reports a socket writable only once half its (autotuned, MiB-sized) send buffer is free."""
    failed: dict[int, str] = {}
    poller = select.poll()
    last_progress: dict[int, float] = {}
    last_unsent: dict[int, int] = {}
    now = time.monotonic()
    for index in behind:
        poller.register(socks[index].fileno(), select.POLLOUT)
        last_progress[index] = now
        last_unsent[index] = unsent_bytes(socks[index])
    tick_ms = max(1, math.ceil(min(stall_s / 4, 0.05) * 1000))
    while behind:
        poller.poll(tick_ms)  # wakes early when one becomes writable; every laggard is looked at each tick
        now = time.monotonic()
        for index in list(behind):
            sock = socks[index]
            try:
                sent = send_now(sock, behind[index])
            except OSError as error:  # e.g. the peer hung up
                failed[index] = str(error)
            else:
                unsent = unsent_bytes(sock)
                if sent or unsent < last_unsent[index]:
                    last_progress[index] = now
                last_unsent[index] = unsent
                behind[index] = behind[index][sent:]
                if behind[index] and now - last_progress[index] >= stall_s:
                    failed[index] = f"the peer took no bytes for {stall_s:g} s"
            if index in failed or not behind[index]:
                del behind[index]
                poller.unregister(sock.fileno())
    return failed
