"""bridge.sockets.send_to_all on real loopback TCP connections: healthy peers get every byte at once, a steady
slow reader is waited for, a peer that stopped reading (or hung up) fails alone. Every case runs with the senders
in blocking mode and in timeout mode (rospy sets a process-wide default socket timeout that new sockets inherit)."""
from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from bridge.sockets import send_now, send_to_all, tune_socket

DATA = bytes(range(256)) * (32 * 1024)  # 8 MiB: more than loopback's socket buffers hold
STALL_S = 1.0  # as the endpoint uses (bridge.ros.SUBSCRIBER_STALL_S)


@pytest.fixture(params=[None, 60.0], ids=["blocking", "timeout-mode"])
def sender_timeout(request) -> float | None:
    return request.param


@contextmanager
def tcp_pairs(count: int, sender_timeout: float | None) -> Iterator[list[tuple[socket.socket, socket.socket]]]:
    """`count` connected (sender, receiver) pairs over loopback; the senders have the given Python timeout."""
    listener = socket.create_server(("127.0.0.1", 0))
    pairs = []
    try:
        for _ in range(count):
            receiver_side = socket.create_connection(listener.getsockname())
            sender, _ = listener.accept()
            sender.settimeout(sender_timeout)
            pairs.append((sender, receiver_side))
        yield pairs
    finally:
        for sender, receiver in pairs:
            sender.close()
            receiver.close()
        listener.close()


class Reader(threading.Thread):
    """Reads a socket until `expected` bytes came, pausing `pause_s` after each chunk of at most `chunk` bytes."""

    def __init__(self, sock: socket.socket, expected: int, pause_s: float = 0.0, chunk: int = 1 << 20) -> None:
        super().__init__(daemon=True)
        self.sock, self.expected, self.pause_s, self.chunk = sock, expected, pause_s, chunk
        self.received = bytearray()
        self.start()

    def run(self) -> None:
        self.sock.settimeout(30)
        while len(self.received) < self.expected:
            data = self.sock.recv(self.chunk)
            if not data:
                return
            self.received += data
            time.sleep(self.pause_s)


def test_every_healthy_peer_gets_all_the_bytes(sender_timeout: float | None) -> None:
    with tcp_pairs(3, sender_timeout) as pairs:
        readers = [Reader(receiver, len(DATA)) for _, receiver in pairs]
        assert send_to_all([sender for sender, _ in pairs], DATA, STALL_S) == {}
        for reader in readers:
            reader.join(10)
            assert bytes(reader.received) == DATA


def test_a_peer_that_stopped_reading_fails_alone_and_the_others_are_not_held_up(sender_timeout: float | None) -> None:
    with tcp_pairs(3, sender_timeout) as pairs:
        healthy = [Reader(pairs[0][1], len(DATA)), Reader(pairs[2][1], len(DATA))]  # pairs[1] never reads
        started = time.monotonic()
        failed = send_to_all([sender for sender, _ in pairs], DATA, STALL_S)
        assert list(failed) == [1] and "took no bytes" in failed[1]
        assert time.monotonic() - started < 10 * STALL_S  # bounded by the stall limit, not by the frozen peer
        for reader in healthy:
            reader.join(10)
            assert bytes(reader.received) == DATA


def test_a_slow_reader_that_keeps_reading_is_waited_for_however_long_it_takes(sender_timeout: float | None) -> None:
    with tcp_pairs(2, sender_timeout) as pairs:
        # 64 KiB every 20 ms: ~2.5 s for the whole, longer than STALL_S, but never STALL_S without progress
        slow = Reader(pairs[0][1], len(DATA), pause_s=0.02, chunk=64 * 1024)
        fast = Reader(pairs[1][1], len(DATA))
        assert send_to_all([sender for sender, _ in pairs], DATA, STALL_S) == {}
        for reader in (slow, fast):
            reader.join(30)
            assert bytes(reader.received) == DATA


def test_a_peer_that_hung_up_fails_with_the_socket_error(sender_timeout: float | None) -> None:
    with tcp_pairs(2, sender_timeout) as pairs:
        pairs[0][1].close()
        healthy = Reader(pairs[1][1], len(DATA))
        failed = send_to_all([sender for sender, _ in pairs], DATA, STALL_S)
        assert list(failed) == [0] and ("reset" in failed[0].lower() or "pipe" in failed[0].lower())
        healthy.join(10)
        assert bytes(healthy.received) == DATA


def test_send_now_returns_at_once_from_a_full_socket_in_either_mode(sender_timeout: float | None) -> None:
    """In timeout mode CPython ignores MSG_DONTWAIT and waits for writability: send_now must not."""
    with tcp_pairs(1, sender_timeout) as [(sender, _)]:
        chunk = bytes(64 * 1024)
        started = time.monotonic()
        total = 0
        for _ in range(10_000):  # the receiver never reads: the buffers fill within a few MiB
            sent = send_now(sender, chunk)
            total += sent
            if sent == 0:
                break
        assert sent == 0 and total > 0
        assert time.monotonic() - started < 30  # with the 60 s timeout honoured, the full socket would wait 60 s


def test_tune_socket_puts_a_client_connection_in_blocking_mode() -> None:
    """Sockets accepted after rospy set its process-wide default timeout (60 s) inherit it; the endpoint's client
    connections must not keep it: the dead-peer timeout is TCP's business (see the next test)."""
    with tcp_pairs(1, 60.0) as [(accepted, _)]:
        tune_socket(accepted, 10.0)
        assert accepted.gettimeout() is None


def test_tune_socket_gives_a_peer_that_takes_nothing_up_after_the_dead_peer_timeout() -> None:
    with tcp_pairs(1, None) as [(accepted, _)]:
        tune_socket(accepted, 2.0)
        assert accepted.getsockopt(socket.IPPROTO_TCP, socket.TCP_USER_TIMEOUT) == 2000
        idle = accepted.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPIDLE)
        interval = accepted.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPINTVL)
        count = accepted.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPCNT)
        assert idle + interval * count <= 2
        started = time.monotonic()
        with pytest.raises(OSError):
            while time.monotonic() - started < 30:  # the peer never reads: its window shuts, then the timeout
                send_now(accepted, b"x" * 65536)
                time.sleep(0.01)
        assert time.monotonic() - started < 15
