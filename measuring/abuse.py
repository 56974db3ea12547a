"""Abuse for the endpoint, shared by the chaos tests (short, bounded) and bench.chaos_bench (minutes long):
connections reset mid-way and mutated streams of valid frames (the endpoint's figures meanwhile: measuring.procfs).
Every loop here is bounded by a count or a deadline."""

from __future__ import annotations

import random
import socket
import struct
import threading
import time
from dataclasses import dataclass

from bridge import protocol

LOOPBACK = "127.0.0.1"
_LINGER_RESET = struct.pack("ii", 1, 0)  # SO_LINGER on, 0 s: close() sends RST, as a crashed client's kernel does


# --- connections that end abruptly ---------------------------------------------------------------------------------


def _valid_command(rng: random.Random) -> bytes:
    topic = f"/chaos_{rng.randrange(50)}"
    return rng.choice(
        (
            protocol.encode_syscommand("__subscribe", {"topic": topic, "message_name": "std_msgs/String"}),
            protocol.encode_syscommand("__publish", {"topic": topic, "message_name": "std_msgs/String"}),
            protocol.encode_syscommand("__topic_list", {}),
            protocol.encode_syscommand("__ping", {"request_time": "2026-11-23T00:00:00+00:00"}),
            protocol.KEEPALIVE_FRAME,
        )
    )


def reset_connection(port: int, rng: random.Random) -> None:
    """Connect, maybe say something (a command, half a frame, a large frame's start), and reset the connection."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.settimeout(5)
    try:
        sock.connect((LOOPBACK, port))
        what = rng.randrange(4)
        if what == 1:
            sock.sendall(_valid_command(rng))
        elif what == 2:
            frame = _valid_command(rng)
            sock.sendall(frame[: rng.randrange(1, len(frame))])
        elif what == 3:
            sock.sendall(struct.pack("<I", 5) + b"/huge" + struct.pack("<I", 32 << 20) + bytes(rng.randrange(65536)))
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, _LINGER_RESET)
    except OSError:
        pass  # turned away (a limit) or reset first: churn all the same
    finally:
        sock.close()


def churn(port: int, count: int, seed: int, deadline: float) -> int:
    """`count` connections reset one after another (fewer if the deadline comes first); how many were made."""
    rng = random.Random(seed)
    made = 0
    while made < count and time.monotonic() < deadline:
        reset_connection(port, rng)
        made += 1
    return made


# --- mutated streams -----------------------------------------------------------------------------------------------


def _valid_stream(rng: random.Random) -> bytes:
    """A client's valid conversation: registrations, messages, queries, a service call, keepalives."""
    topic = f"/chaos_{rng.randrange(20)}"
    text = "x" * rng.randrange(200)
    message = struct.pack("<I", len(text)) + text.encode()
    parts = [
        protocol.encode_syscommand("__publish", {"topic": topic, "message_name": "std_msgs/String", "queue_size": 5}),
        protocol.encode_syscommand("__subscribe", {"topic": topic, "message_name": "std_msgs/String"}),
        *[protocol.encode_frame(topic, message) for _ in range(rng.randrange(1, 20))],
        protocol.encode_syscommand("__topic_list", {}),
        protocol.encode_syscommand("__ros_service", {"topic": "/chaos_srv", "message_name": "std_srvs/Trigger"}),
        protocol.encode_syscommand("__request", {"srv_id": rng.randrange(1 << 16)})
        + protocol.encode_frame("/chaos_srv", b""),
        protocol.encode_syscommand("__ping", {"request_time": "t"}),
        protocol.KEEPALIVE_FRAME,
        protocol.encode_syscommand("__remove_publisher", {"topic": topic}),
    ]
    rng.shuffle(parts)
    return b"".join(parts)


def mutated_stream(rng: random.Random) -> bytes:
    """A valid stream with a few mutations: bytes flipped, inserted or cut, lengths made large, JSON nested deep,
    now and then a large frame begun and abandoned (the bad length after it loses the framing)."""
    data = bytearray(_valid_stream(rng))
    for _ in range(rng.randrange(1, 6)):
        kind = rng.randrange(6)
        at = rng.randrange(len(data))
        if kind == 0:
            data[at] ^= 1 << rng.randrange(8)
        elif kind == 1:
            data[at:at] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 16)))
        elif kind == 2:
            del data[at : at + rng.randrange(1, 32)]
        elif kind == 3 and at + 4 <= len(data):
            data[at : at + 4] = struct.pack("<I", rng.choice((0xFFFFFFFF, 1 << 24, 1 << 30, rng.randrange(1 << 20))))
        elif kind == 4:
            data[at:at] = protocol.encode_frame("__subscribe", b"[" * 5000 + b"]" * 5000)
        elif kind == 5 and rng.random() < 0.2:
            data[at:at] = struct.pack("<I", 4) + b"/big" + struct.pack("<I", 8 << 20) + bytes(1 << 20)
    return bytes(data)


@dataclass
class FuzzStats:
    connections: int = 0
    bytes_sent: int = 0


def fuzz_client(port: int, seed: int, stop: threading.Event, stats: FuzzStats) -> None:
    """Send mutated streams until `stop`, reconnecting whenever the endpoint closes the connection; what comes back
    is read and thrown away (a fuzzer that reads nothing is the unread-answers case, tested on its own)."""
    rng = random.Random(seed)
    while not stop.is_set():
        try:
            with socket.create_connection((LOOPBACK, port), timeout=5) as sock:
                stats.connections += 1
                sock.settimeout(0.05)
                for _ in range(rng.randrange(1, 30)):
                    if stop.is_set():
                        break
                    data = mutated_stream(rng)
                    sock.sendall(data)
                    stats.bytes_sent += len(data)
                    try:
                        while sock.recv(1 << 20):
                            pass
                    except socket.timeout:
                        pass
        except OSError:
            pass  # closed by the endpoint (framing lost, a limit): a new connection
