"""bridge.connection.sockets.send_to_all on real loopback TCP connections: healthy peers get every byte at once, a
steady slow reader is waited for, a peer that stopped reading (or hung up) fails alone. Every case runs with the senders
in blocking mode and in timeout mode (rospy sets a process-wide default socket timeout that new sockets inherit)."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from bridge.connection.sockets import (
    BEHIND_BYTES,
    NOTSENT_LOWAT_BYTES,
    PACING_CONGESTION_CONTROLS,
    TCP_NOTSENT_LOWAT,
    UnsentLimit,
    send_now,
    send_to_all,
    takes_whole,
    tune_socket,
    unsent_bytes,
)

pytestmark = pytest.mark.lane("endpoint", on=("noetic",))

DATA = bytes(range(256)) * (32 * 1024)  # 8 MiB: more than loopback's socket buffers hold
STALL_S = 1.0  # as the endpoint uses (bridge.ros.publisher.SUBSCRIBER_STALL_S)


@pytest.fixture(params=[None, 60.0], ids=["blocking", "timeout-mode"])
def sender_timeout(request) -> float | None:
    return request.param


@contextmanager
def tcp_pairs(
    count: int, sender_timeout: float | None, host: str = "127.0.0.1"
) -> Iterator[list[tuple[socket.socket, socket.socket]]]:
    """`count` connected (sender, receiver) pairs over loopback; the senders have the given Python timeout."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    listener = socket.create_server((host, 0), family=family)
    pairs = []
    try:
        for _ in range(count):
            receiver_side = socket.create_connection(listener.getsockname()[:2])
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


def congestion_control(sock: socket.socket) -> bytes:
    return sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_CONGESTION, 16).rstrip(b"\0")


@pytest.mark.parametrize("host", ["127.0.0.1", "::1"])
def test_tune_socket_does_not_pace_a_client_on_this_machine(host: str) -> None:
    """BBR's pacing stalled 1 MiB round trips to a local client for 40-115 ms
    (bridge.connection.sockets.unpaced_on_loopback)."""
    if not socket.has_ipv6 and ":" in host:
        pytest.skip("no IPv6")
    with tcp_pairs(1, None, host) as [(accepted, _)]:
        try:
            accepted.setsockopt(socket.IPPROTO_TCP, socket.TCP_CONGESTION, b"bbr")
        except OSError:
            pytest.skip("this kernel has no BBR, or does not allow it to this user")
        tune_socket(accepted, 10.0)
        assert congestion_control(accepted) not in PACING_CONGESTION_CONTROLS


def test_the_unsent_limit_is_left_off_while_the_peer_keeps_up() -> None:
    with tcp_pairs(1, None) as [(sender, receiver)]:
        limit = UnsentLimit(sender)
        for _ in range(20):
            limit.before_large_write()
            sender.sendall(DATA[: 1 << 20])
            received = 0
            while received < 1 << 20:
                received += len(receiver.recv(1 << 20))
        assert not limit.limited
        assert sender.getsockopt(socket.IPPROTO_TCP, TCP_NOTSENT_LOWAT) == 0


def test_the_unsent_limit_is_set_once_a_large_write_finds_the_peer_behind() -> None:
    with tcp_pairs(1, None) as [(sender, _)]:
        limit = UnsentLimit(sender)
        limit.before_large_write()
        assert not limit.limited
        deadline = time.monotonic() + 10
        while unsent_bytes(sender) < BEHIND_BYTES and time.monotonic() < deadline:
            if not send_now(sender, DATA[: 1 << 20]):
                time.sleep(0.01)
        limit.before_large_write()
        assert limit.limited
        assert sender.getsockopt(socket.IPPROTO_TCP, TCP_NOTSENT_LOWAT) == NOTSENT_LOWAT_BYTES


def test_takes_whole_is_half_the_send_buffer_and_one_write_to_an_idle_socket_takes_that_much() -> None:
    with tcp_pairs(1, None) as [(sender, _)]:
        half = sender.getsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF) // 2
        assert takes_whole(sender, half) and not takes_whole(sender, half + 1)
        assert send_now(sender, bytes(half)) == half  # the peer reads nothing meanwhile
