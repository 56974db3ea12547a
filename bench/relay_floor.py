"""What any relay adds to a 1 MiB round trip on this machine: the floor under the endpoint's round-trip figure.

Run: `.venv/bin/python -m bench.relay_floor [--samples N] [--rounds R]`.

The endpoint's 1 MiB round trip (bench.endpoint_bench, `large`) moves the message four times over loopback
(client -> endpoint -> echo node -> endpoint -> client) where rospy alone moves it twice (node -> echo node -> node).
This bench measures the same shape with bare sockets, no ROS, no framing work, so that the cost of the two extra
moves is seen alone:

  direct   a client sends 1 MiB (u32 length + bytes) to an echo process, which sends it back;
  relayed  the same through a relay process that takes each message whole and passes it on, both ways.

Every process receives into a buffer allocated once (recv_into), so no allocator work is counted, and every
connection is TCP_NODELAY with an unpaced congestion control (cubic), as the endpoint's local connections are.
The two paths take turns sample by sample at 30 Hz; p50 and p99 of each, what the relay adds and the ratio are
printed per round. Every loop is bounded in count; every process is stopped at the end.
"""

from __future__ import annotations

import argparse
import multiprocessing
import socket
import statistics
import struct
import time
from multiprocessing.queues import Queue
from typing import Any

from measuring.stats import percentile

MESSAGE_BYTES = 1 << 20
_LENGTH = struct.Struct("<I")


def _connected(sock: socket.socket) -> socket.socket:
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    congestion = getattr(socket, "TCP_CONGESTION", None)
    if congestion is not None:
        try:
            sock.setsockopt(socket.IPPROTO_TCP, congestion, b"cubic")
        except OSError:  # not built into this kernel: the system's choice stays
            pass
    return sock


def _receive_exactly(sock: socket.socket, view: memoryview) -> bool:
    """Fill `view` from `sock`; False when the peer closed first."""
    received = 0
    while received < len(view):
        count = sock.recv_into(view[received:])
        if not count:
            return False
        received += count
    return True


class Channel:
    """Length-prefixed messages over one connection, received into one buffer of MESSAGE_BYTES."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = _connected(sock)
        self._buffer = bytearray(MESSAGE_BYTES)
        self._view = memoryview(self._buffer)
        self._header = bytearray(4)

    def receive(self) -> memoryview | None:
        if not _receive_exactly(self.sock, memoryview(self._header)):
            return None
        (length,) = _LENGTH.unpack(self._header)
        body = self._view[:length]
        return body if _receive_exactly(self.sock, body) else None

    def send(self, message: bytes | memoryview) -> None:
        self.sock.sendall(_LENGTH.pack(len(message)))
        self.sock.sendall(message)


def _listen(ports: Queue[int]) -> socket.socket:
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    ports.put(server.getsockname()[1])
    return server


def echo(ports: Queue[int]) -> None:
    channel = Channel(_listen(ports).accept()[0])
    while (message := channel.receive()) is not None:
        channel.send(message)


def relay(upstream_port: int, ports: Queue[int]) -> None:
    upstream = Channel(socket.create_connection(("127.0.0.1", upstream_port)))
    client = Channel(_listen(ports).accept()[0])
    while (message := client.receive()) is not None:
        upstream.send(message)
        answer = upstream.receive()
        if answer is None:
            return
        client.send(answer)


def round_trip_ms(channel: Channel, message: bytes) -> float:
    started = time.perf_counter()
    channel.send(message)
    if channel.receive() is None:
        raise SystemExit("relay_floor: a helper process closed its connection")
    return (time.perf_counter() - started) * 1000.0


def one_round(samples: int) -> tuple[list[float], list[float]]:
    ports: Queue[int] = multiprocessing.Queue()
    processes: list[Any] = []
    try:
        for target, args in ((echo, (ports,)), (echo, (ports,))):
            processes.append(multiprocessing.Process(target=target, args=args, daemon=True))
            processes[-1].start()
        direct_port, relayed_echo_port = ports.get(timeout=10), ports.get(timeout=10)
        processes.append(multiprocessing.Process(target=relay, args=(relayed_echo_port, ports), daemon=True))
        processes[-1].start()
        relay_port = ports.get(timeout=10)
        direct = Channel(socket.create_connection(("127.0.0.1", direct_port)))
        relayed = Channel(socket.create_connection(("127.0.0.1", relay_port)))
        message = bytes(MESSAGE_BYTES)
        times: dict[str, list[float]] = {"direct": [], "relayed": []}
        for index in range(samples):
            order = (("direct", direct), ("relayed", relayed))
            for name, channel in order if index % 2 else order[::-1]:
                times[name].append(round_trip_ms(channel, message))
                time.sleep(1 / 30)
        direct.sock.close()
        relayed.sock.close()
        return times["direct"], times["relayed"]
    finally:
        for process in processes:
            process.terminate()
            process.join(timeout=5)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=int, default=300, help="round trips per path per round (default 300)")
    parser.add_argument("--rounds", type=int, default=3, help="rounds, each with fresh processes (default 3)")
    args = parser.parse_args()
    if not 10 <= args.samples <= 10_000 or not 1 <= args.rounds <= 20:
        parser.error("--samples must be 10..10000 and --rounds 1..20")
    print(f"1 MiB round trips at 30 Hz over loopback, {args.samples} per path per round, paths taking turns")
    print(
        f"{'round':>5}  {'direct p50':>10}  {'relayed p50':>11}  {'relay adds':>10}  {'ratio':>5}  "
        f"{'direct p99':>10}  {'relayed p99':>11}"
    )
    for number in range(1, args.rounds + 1):
        direct, relayed = one_round(args.samples)
        d50, r50 = statistics.median(direct), statistics.median(relayed)
        print(
            f"{number:>5}  {d50:>8.2f}ms  {r50:>9.2f}ms  {r50 - d50:>8.2f}ms  {r50 / d50:>5.2f}  "
            f"{percentile(direct, 99):>8.2f}ms  {percentile(relayed, 99):>9.2f}ms"
        )


if __name__ == "__main__":
    main()
