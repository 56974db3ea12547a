"""bridge.sockets.send_to_all on real loopback TCP connections: healthy peers get every byte at once, a steady
slow reader is waited for, a peer that stopped reading (or hung up) fails alone."""
from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

from bridge.sockets import send_to_all

DATA = bytes(range(256)) * (32 * 1024)  # 8 MiB: more than loopback's socket buffers hold
STALL_S = 1.0  # as the endpoint uses (bridge.ros.SUBSCRIBER_STALL_S)


@contextmanager
def tcp_pairs(count: int) -> Iterator[list[tuple[socket.socket, socket.socket]]]:
    """`count` connected (sender, receiver) pairs over loopback."""
    listener = socket.create_server(("127.0.0.1", 0))
    pairs = []
    try:
        for _ in range(count):
            receiver_side = socket.create_connection(listener.getsockname())
            sender, _ = listener.accept()
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


def test_every_healthy_peer_gets_all_the_bytes() -> None:
    with tcp_pairs(3) as pairs:
        readers = [Reader(receiver, len(DATA)) for _, receiver in pairs]
        assert send_to_all([sender for sender, _ in pairs], DATA, STALL_S) == {}
        for reader in readers:
            reader.join(10)
            assert bytes(reader.received) == DATA


def test_a_peer_that_stopped_reading_fails_alone_and_the_others_are_not_held_up() -> None:
    with tcp_pairs(3) as pairs:
        healthy = [Reader(pairs[0][1], len(DATA)), Reader(pairs[2][1], len(DATA))]  # pairs[1] never reads
        started = time.monotonic()
        failed = send_to_all([sender for sender, _ in pairs], DATA, STALL_S)
        assert list(failed) == [1] and "took no bytes" in failed[1]
        assert time.monotonic() - started < 10 * STALL_S  # bounded by the stall limit, not by the frozen peer
        for reader in healthy:
            reader.join(10)
            assert bytes(reader.received) == DATA


def test_a_slow_reader_that_keeps_reading_is_waited_for_however_long_it_takes() -> None:
    with tcp_pairs(2) as pairs:
        # 64 KiB every 20 ms: ~2.5 s for the whole, longer than STALL_S, but never STALL_S without progress
        slow = Reader(pairs[0][1], len(DATA), pause_s=0.02, chunk=64 * 1024)
        fast = Reader(pairs[1][1], len(DATA))
        assert send_to_all([sender for sender, _ in pairs], DATA, STALL_S) == {}
        for reader in (slow, fast):
            reader.join(30)
            assert bytes(reader.received) == DATA


def test_a_peer_that_hung_up_fails_with_the_socket_error() -> None:
    with tcp_pairs(2) as pairs:
        pairs[0][1].close()
        healthy = Reader(pairs[1][1], len(DATA))
        failed = send_to_all([sender for sender, _ in pairs], DATA, STALL_S)
        assert list(failed) == [0] and ("reset" in failed[0].lower() or "pipe" in failed[0].lower())
        healthy.join(10)
        assert bytes(healthy.received) == DATA
