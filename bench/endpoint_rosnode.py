"""Plain rospy nodes for the endpoint benchmark, one role per process (so no two roles share a GIL). Run from the
repository root as `python -m bench.endpoint_rosnode ROLE ...` (on Noetic's Python 3.8 too: standard library,
rospy and bench.messages only).

Roles (first argument):
  count  - subscribe to a topic, count messages until idle; print CONNECTED once a publisher is connected.
  flood  - publish pre-serialized messages as fast as rospy allows, bounded by count and time.
  rate   - publish stamped messages (header.seq = 0, 1, ...) at a fixed rate, bounded by count and time.
  relay  - republish the bytes received on IN unchanged on OUT (ping -> pong), until killed.
  ping   - pure rospy round trip through `relay`: publish stamped pings, time the pongs.
  stream - publish several stamped topics at their own rates (KIND:TOPIC:HZ each), bounded in time.
  ages   - subscribe to several topics (KIND:TOPIC each) and record every message's arrival and age (arrival time
           minus its header stamp, both CLOCK_MONOTONIC) for a given time, or until the messages stop (--idle).

Every node uses a raw message class: it carries the message type's name/md5/definition (JointState unless `--kind`
names another of bench.messages.MESSAGE_KINDS), so rospy negotiates exactly as for the generated class, but it
serializes stored bytes and deserializes by keeping them (the same bytes-only path the endpoint uses), so the rospy
figures are a transport ceiling, not a (de)serialization benchmark.
Results go to stdout as one line `RESULT <json>`.
"""

from __future__ import annotations

import argparse
import gc
import json
import time
from typing import Any

import genpy
import roslib.message
import rospy

from bench.messages import HEADER_OFFSETS, MESSAGE_KINDS, paced, read_stamp, stamped


class RawMessage(genpy.Message):
    """A message on the wire, bytes in Python: serialize writes `_buff`, deserialize keeps the bytes. Subclassed
    per type by `raw_class`."""

    __slots__ = ("_buff",)
    _has_header = False  # rospy must not rewrite header.seq
    _slot_types: list[str] = []

    def __init__(self, buff: bytes = b"") -> None:
        self._buff = buff

    def serialize(self, buff: Any) -> None:
        buff.write(self._buff)

    def deserialize(self, data: bytes) -> RawMessage:
        self._buff = data
        return self


def raw_class(message_name: str) -> type[RawMessage]:
    """RawMessage carrying `message_name`'s type, md5 and definition, for rospy's connection header."""
    generated = roslib.message.get_message_class(message_name)
    if generated is None:
        raise SystemExit(f"endpoint_rosnode: no generated class for {message_name}")
    return type(
        f"Raw{generated.__name__}",
        (RawMessage,),
        {
            "__slots__": (),
            "_type": generated._type,
            "_md5sum": generated._md5sum,
            "_full_text": generated._full_text,
        },
    )


def emit(kind: str, **fields: Any) -> None:
    print(f"{kind} {json.dumps(fields)}", flush=True)


def wait_for_connections(endpoint: Any, wanted: int, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while endpoint.get_num_connections() < wanted:
        if time.monotonic() > deadline or rospy.is_shutdown():
            return False
        time.sleep(0.01)
    return True


def run_count(args: argparse.Namespace) -> None:
    state = {"count": 0, "first": 0, "last": 0}

    def on_message(_: RawMessage) -> None:
        now = time.monotonic_ns()
        if state["count"] == 0:
            state["first"] = now
        state["count"] += 1
        state["last"] = now

    subscriber = rospy.Subscriber(args.topic, args.raw, on_message, tcp_nodelay=True)
    if wait_for_connections(subscriber, 1, args.max_seconds):
        print("CONNECTED", flush=True)
    deadline = time.monotonic() + args.max_seconds
    while time.monotonic() < deadline and not rospy.is_shutdown():
        time.sleep(0.05)
        if state["count"] and time.monotonic_ns() - state["last"] > args.idle * 1e9:
            break
    emit("RESULT", **state)


def run_flood(args: argparse.Namespace) -> None:
    # queue size 0 = rospy's synchronous publish (the caller's thread writes the socket)
    publisher = rospy.Publisher(args.topic, args.raw, queue_size=args.queue_size or None)
    connected = wait_for_connections(publisher, args.subscribers, 30.0)
    time.sleep(args.delay)
    message = args.raw(args.payload())
    sent = 0
    start = time.monotonic()
    deadline = start + args.seconds
    # check the clock once per 100 messages: the loop itself is what is being measured
    while sent < args.count and (sent % 100 or time.monotonic() < deadline):
        publisher.publish(message)
        sent += 1
    emit("RESULT", sent=sent, seconds=time.monotonic() - start, connected=connected)
    time.sleep(0.5)  # let rospy's writer threads flush the queue before the process goes


def run_rate(args: argparse.Namespace) -> None:
    publisher = rospy.Publisher(args.topic, args.raw, queue_size=args.queue_size)
    connected = wait_for_connections(publisher, args.subscribers, 30.0)
    time.sleep(args.delay)
    template = args.payload()
    print("PUBLISHING", flush=True)
    sent = 0
    for seq in paced(args.hz, args.count, args.seconds):
        publisher.publish(args.raw(stamped(template, seq)))
        sent += 1
    emit("RESULT", sent=sent, connected=connected)
    time.sleep(0.5)


def run_relay(args: argparse.Namespace) -> None:
    for pair in args.pair:
        source, target = pair.split(":")
        publisher = rospy.Publisher(target, args.raw, queue_size=100, tcp_nodelay=True)
        rospy.Subscriber(source, args.raw, publisher.publish, tcp_nodelay=True)
    print("READY", flush=True)
    rospy.spin()


def run_ping(args: argparse.Namespace) -> None:
    rtts_us: list[float] = []

    def on_pong(message: RawMessage) -> None:
        _, stamp_ns = read_stamp(message._buff)
        rtts_us.append((time.monotonic_ns() - stamp_ns) / 1000.0)

    publisher = rospy.Publisher(args.out_topic, args.raw, queue_size=100, tcp_nodelay=True)
    subscriber = rospy.Subscriber(args.in_topic, args.raw, on_pong, tcp_nodelay=True)
    wait_for_connections(publisher, 1, 30.0)
    wait_for_connections(subscriber, 1, 30.0)
    template = args.payload()
    # warm up: ping every 10 ms until the first pong is back (the relay's outgoing link is then up)
    for seq in paced(100, 1000, 10.0):
        if rtts_us:
            break
        publisher.publish(args.raw(stamped(template, seq)))
    time.sleep(0.5)
    results: dict[str, dict[str, Any]] = {}
    for spec in args.rates:
        hz, count = (int(part) for part in spec.split(":"))
        rtts_us.clear()
        sent = 0
        for seq in paced(hz, count, count / hz * 1.5 + 2.0):
            publisher.publish(args.raw(stamped(template, seq)))
            sent += 1
        time.sleep(0.5)  # stragglers
        results[str(hz)] = {"sent": sent, "rtts_us": list(rtts_us)}
    emit("RESULT", rates=results)


def run_stream(args: argparse.Namespace) -> None:
    streams = []
    for spec in args.stream:
        kind, topic, hz = spec.split(":")
        message_name, make_payload = MESSAGE_KINDS[kind]
        large = kind in ("image", "vga_image", "cloud")  # a camera driver keeps only the newest frame queued
        raw = raw_class(message_name)
        publisher = rospy.Publisher(topic, raw, queue_size=1 if large else 100, tcp_nodelay=True)
        streams.append((topic, raw, publisher, make_payload(), HEADER_OFFSETS.get(kind, 0), 1.0 / float(hz)))
    connected = all(wait_for_connections(stream[2], args.subscribers, 30.0) for stream in streams)
    time.sleep(args.delay)
    print("PUBLISHING", flush=True)
    sent = {stream[0]: 0 for stream in streams}
    start = time.monotonic()
    due = [start] * len(streams)
    while not rospy.is_shutdown():
        index = min(range(len(streams)), key=due.__getitem__)
        if due[index] - start > args.seconds:
            break
        pause = due[index] - time.monotonic()
        if pause > 0:
            time.sleep(pause)
        topic, raw, publisher, template, offset, period = streams[index]
        publisher.publish(raw(stamped(template, sent[topic], offset=offset)))
        sent[topic] += 1
        due[index] += period  # a fixed schedule: a late message does not move the next one
    emit("RESULT", sent=sent, connected=connected)
    time.sleep(0.5)


def run_ages(args: argparse.Namespace) -> None:
    records: dict[str, list[tuple[int, int]]] = {}
    last_ns = [0]  # the latest arrival on any topic
    subscribers = []
    for spec in args.listen:
        kind, topic = spec.split(":")
        offset = HEADER_OFFSETS.get(kind, 0)
        arrivals = records.setdefault(topic, [])

        def on_message(message: RawMessage, arrivals: list = arrivals, offset: int = offset) -> None:
            now = time.monotonic_ns()
            arrivals.append((now, now - read_stamp(message._buff, offset)[1]))
            last_ns[0] = now

        subscribers.append(
            rospy.Subscriber(topic, raw_class(MESSAGE_KINDS[kind][0]), on_message, tcp_nodelay=True, buff_size=1 << 22)
        )
    if all(wait_for_connections(subscriber, 1, 30.0) for subscriber in subscribers):
        print("CONNECTED", flush=True)
    deadline = time.monotonic() + args.seconds
    while time.monotonic() < deadline and not rospy.is_shutdown():
        time.sleep(0.05)
        if args.idle and last_ns[0] and time.monotonic_ns() - last_ns[0] > args.idle * 1e9:
            break  # the sender is done: its last message is this long ago
    emit("RESULT", arrivals={topic: [list(pair) for pair in pairs] for topic, pairs in records.items()})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    roles = parser.add_subparsers(dest="role", required=True)
    count = roles.add_parser("count")
    count.add_argument("--topic", required=True)
    count.add_argument("--idle", type=float, default=1.0, help="stop this long after the last message")
    count.add_argument("--max-seconds", type=float, default=60.0)
    flood = roles.add_parser("flood")
    flood.add_argument("--topic", required=True)
    flood.add_argument("--seconds", type=float, default=5.0)
    flood.add_argument("--count", type=int, default=5_000_000)
    flood.add_argument("--subscribers", type=int, default=1)
    flood.add_argument("--delay", type=float, default=0.3)
    flood.add_argument("--queue-size", type=int, default=100)
    rate = roles.add_parser("rate")
    rate.add_argument("--topic", required=True)
    rate.add_argument("--hz", type=float, default=1000.0)
    rate.add_argument("--seconds", type=float, default=5.0)
    rate.add_argument("--count", type=int, default=10_000_000)
    rate.add_argument("--subscribers", type=int, default=1)
    rate.add_argument("--delay", type=float, default=0.5)
    rate.add_argument("--queue-size", type=int, default=1000)
    relay = roles.add_parser("relay")
    relay.add_argument("--pair", action="append", required=True, metavar="IN:OUT")
    ping = roles.add_parser("ping")
    ping.add_argument("--out-topic", required=True)
    ping.add_argument("--in-topic", required=True)
    ping.add_argument("--rates", nargs="+", required=True, metavar="HZ:COUNT")
    stream = roles.add_parser("stream")
    stream.add_argument("--stream", action="append", required=True, metavar="KIND:TOPIC:HZ")
    stream.add_argument("--seconds", type=float, default=60.0)
    stream.add_argument("--subscribers", type=int, default=1)
    stream.add_argument("--delay", type=float, default=0.5)
    ages = roles.add_parser("ages")
    ages.add_argument("--listen", action="append", required=True, metavar="KIND:TOPIC")
    ages.add_argument("--seconds", type=float, default=60.0, help="listen this long at most")
    ages.add_argument("--idle", type=float, default=0.0, help="stop this long after the last message (0: never)")
    for role in (count, flood, rate, relay, ping, stream, ages):
        role.add_argument("--kind", choices=sorted(MESSAGE_KINDS), default="joint_state", help="message kind")
    args = parser.parse_args(rospy.myargv()[1:])
    if "kind" in args:
        message_name, args.payload = MESSAGE_KINDS[args.kind]
        args.raw = raw_class(message_name)

    rospy.init_node(f"bench_{args.role}", anonymous=True)
    gc.collect()  # as the endpoint does: start-up objects out of the cyclic GC's view (see endpoint_bench.main)
    gc.freeze()
    roles_run = {
        "count": run_count,
        "flood": run_flood,
        "rate": run_rate,
        "relay": run_relay,
        "ping": run_ping,
        "stream": run_stream,
        "ages": run_ages,
    }
    roles_run[args.role](args)


if __name__ == "__main__":
    main()
