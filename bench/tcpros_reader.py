"""A raw TCPROS subscriber for the endpoint benchmark: the reference its ROS->TCP rows are divided by.

A rospy subscriber's Python read path copies every message several times, so it measures rospy's reader, not what
a publisher delivers. This process subscribes the way a fast reader would: it asks the master for the topic's
publishers (registerSubscriber), a publisher for its TCPROS address (requestTopic), does the connection handshake
itself (rosgraph's header encoding), and then reads each length-prefixed message straight into one reused buffer
with recv_into, counting them. It never looks at the bytes.

Run: python -m bench.tcpros_reader --topic TOPIC [--kind KIND] [--max-seconds S] [--idle S] [--count N]
Prints CONNECTED after the handshake, then one line `RESULT <json>` (count, first and last arrival [monotonic ns],
bytes) once the publisher closes the connection, nothing came for --idle seconds, or --count / --max-seconds is
reached.
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import struct
import threading
import time
import xmlrpc.client
from typing import Any
from xmlrpc.server import SimpleXMLRPCServer

import rosgraph
import rosgraph.network
import roslib.message

from bench.messages import MESSAGE_KINDS

_U32 = struct.Struct("<I")


def receive_into(sock: socket.socket, view: memoryview) -> bool:
    """Fill `view` from `sock`; False when the peer closed the connection first."""
    while view:
        received = sock.recv_into(view)
        if not received:
            return False
        view = view[received:]
    return True


def read_header(sock: socket.socket) -> dict[str, str]:
    """The publisher's connection header, read exactly (no byte of the first message with it)."""
    prefix = bytearray(4)
    if not receive_into(sock, memoryview(prefix)):
        raise SystemExit("tcpros_reader: the publisher closed the connection before its header")
    body = bytearray(_U32.unpack(prefix)[0])
    if not receive_into(sock, memoryview(body)):
        raise SystemExit("tcpros_reader: the publisher closed the connection inside its header")
    return rosgraph.network.decode_ros_handshake_header(bytes(prefix + body))


def serve_slave_api() -> tuple[str, SimpleXMLRPCServer]:
    """A minimal slave API, so the master's publisherUpdate calls to this subscriber reach a live server (this
    process polls the master instead of acting on them)."""
    server = SimpleXMLRPCServer(("127.0.0.1", 0), logRequests=False, allow_none=True)
    server.register_function(lambda caller_id, topic, publishers: [1, "", 0], "publisherUpdate")
    threading.Thread(target=server.serve_forever, name="slave-api", daemon=True).start()
    return f"http://127.0.0.1:{server.server_address[1]}/", server


def connect(caller_id: str, topic: str, message_name: str, md5sum: str, timeout_s: float) -> socket.socket:
    """Register as subscriber, wait (bounded) for a publisher, and open its TCPROS connection with the handshake."""
    master: Any = xmlrpc.client.ServerProxy(rosgraph.get_master_uri())  # XML-RPC answers: untyped
    caller_api, server = serve_slave_api()
    deadline = time.monotonic() + timeout_s
    try:
        while True:  # registering again is harmless, and answers with the publishers of now
            code, message, publishers = master.registerSubscriber(caller_id, topic, message_name, caller_api)
            if code != 1:
                raise SystemExit(f"tcpros_reader: registerSubscriber failed: {message}")
            if publishers:
                break
            if time.monotonic() > deadline:
                raise SystemExit(f"tcpros_reader: no publisher of {topic} within {timeout_s:g} s")
            time.sleep(0.02)
        publisher: Any = xmlrpc.client.ServerProxy(publishers[0])
        code, message, protocol = publisher.requestTopic(caller_id, topic, [["TCPROS"]])
        if code != 1 or not protocol or protocol[0] != "TCPROS":
            raise SystemExit(f"tcpros_reader: requestTopic failed: {message} {protocol}")
        sock = socket.create_connection((protocol[1], protocol[2]), timeout=10.0)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        header = {"callerid": caller_id, "topic": topic, "md5sum": md5sum, "type": message_name, "tcp_nodelay": "1"}
        sock.sendall(rosgraph.network.encode_ros_handshake_header(header))
        answer = read_header(sock)
        if "error" in answer:
            raise SystemExit(f"tcpros_reader: the publisher refused: {answer['error']}")
        return sock
    finally:
        master.unregisterSubscriber(caller_id, topic, caller_api)  # the connection stands without it
        server.shutdown()
        server.server_close()


def count_messages(sock: socket.socket, max_count: int, max_seconds: float, idle_s: float) -> dict[str, int]:
    """Read whole messages into one buffer (grown only for a larger message) until the publisher goes, `idle_s`
    passes without a byte after the first message, or `max_count` / `max_seconds` is reached."""
    sock.settimeout(max_seconds)  # the publisher may take a while to start; once it has, a pause means it is done
    prefix = memoryview(bytearray(4))
    buffer = memoryview(bytearray(0))
    count, first_ns, last_ns, total = 0, 0, 0, 0
    deadline = time.monotonic() + max_seconds
    while count < max_count and time.monotonic() < deadline:
        try:
            if not receive_into(sock, prefix):
                break
            (size,) = _U32.unpack(prefix)
            if size > len(buffer):
                buffer = memoryview(bytearray(size))
            if not receive_into(sock, buffer[:size]):
                break
        except (TimeoutError, ConnectionResetError):
            break
        now = time.monotonic_ns()
        if count == 0:
            first_ns = now
            sock.settimeout(idle_s)
        count += 1
        last_ns = now
        total += size
    return {"count": count, "first": first_ns, "last": last_ns, "bytes": total}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--topic", required=True)
    parser.add_argument("--kind", choices=sorted(MESSAGE_KINDS), default="joint_state", help="message kind")
    parser.add_argument("--idle", type=float, default=1.0, help="stop this long after the last byte")
    parser.add_argument("--max-seconds", type=float, default=60.0, help="bound of the wait and of the reading")
    parser.add_argument("--count", type=int, default=5_000_000, help="stop after this many messages")
    args = parser.parse_args()
    message_name = MESSAGE_KINDS[args.kind][0]
    generated = roslib.message.get_message_class(message_name)
    if generated is None:
        raise SystemExit(f"tcpros_reader: no generated class for {message_name}")
    caller_id = f"/bench_tcpros_reader_{os.getpid()}"
    with connect(caller_id, args.topic, message_name, generated._md5sum, args.max_seconds) as sock:
        print("CONNECTED", flush=True)
        result = count_messages(sock, args.count, args.max_seconds, args.idle)
    print(f"RESULT {json.dumps(result)}", flush=True)


if __name__ == "__main__":
    main()
