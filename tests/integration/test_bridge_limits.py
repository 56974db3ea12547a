"""Limits per client and overall: past one, a clear __error; the client stays connected where that is safe; threads,
descriptors and memory are bounded by the limits, not by what a client asks for, and released when it leaves."""

from __future__ import annotations

import json
import socket
import struct
import threading
import time
from pathlib import Path

import pytest

from bridge import protocol
from bridge.admission.room import FRAME_GRACE_S
from bridge.protocol import FrameDecoder
from measuring.endpoint import settled
from measuring.frames import Frame, feed
from measuring.procfs import figures
from tests.integration.bridge_helpers import LOOPBACK, RawConnection, start_endpoint, unique
from tests.rosenv import wait_for


def connect_from(port: int, source: str) -> tuple[socket.socket, Frame | None]:
    """A connection from `source` (a loopback address) and the first frame the endpoint sends on it (None if it
    closes the connection without one)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.bind((source, 0))
    sock.settimeout(10)
    sock.connect((LOOPBACK, port))
    decoder = FrameDecoder()
    while True:
        data = sock.recv(65536)
        if not data:
            return sock, None
        frames = feed(decoder, data)
        if frames:
            return sock, frames[0]


def refusal(port: int, source: str) -> str:
    """The reason the endpoint gives a client from `source` for turning it away (and it closes the connection)."""
    sock, frame = connect_from(port, source)
    with sock:
        assert frame is not None and frame.destination == "__error", frame
        assert sock.recv(1) == b""
    return json.loads(frame.payload)["text"]


def test_clients_past_the_limits_are_turned_away_with_the_reason(roscore, ros_node, tmp_path: Path) -> None:
    endpoint = start_endpoint(roscore, tmp_path, "--max-clients", "3", "--max-clients-per-address", "2")
    try:
        first, second = RawConnection(endpoint.port), RawConnection(endpoint.port)  # from 127.0.0.1
        assert "--max-clients-per-address" in refusal(endpoint.port, "127.0.0.1")
        third, handshake = connect_from(endpoint.port, "127.0.0.2")  # another address may still come
        assert handshake is not None and handshake.destination == "__handshake"
        assert "--max-clients)" in refusal(endpoint.port, "127.0.0.3")
        first.sync()  # those connected are served all along
        second.close()

        def admitted() -> bool:
            sock, frame = connect_from(endpoint.port, "127.0.0.1")
            sock.close()
            return frame is not None and frame.destination == "__handshake"

        wait_for(admitted, 10, "room again once a client left")
        third.close()
        first.close()
    finally:
        endpoint.stop()


def test_a_full_endpoint_says_so_to_everyone(roscore, ros_node, tmp_path: Path) -> None:
    endpoint = start_endpoint(roscore, tmp_path, "--max-clients", "1")
    try:
        with RawConnection(endpoint.port) as only:
            assert "--max-clients)" in refusal(endpoint.port, "127.0.0.3")
            only.sync()
    finally:
        endpoint.stop()


class SlowSender(threading.Thread):
    """A slow-loris client from `source`: a frame that never ends, one byte every `interval_s`, until stopped or
    closed by the endpoint; `admitted` once it got the handshake, and the endpoint's reasons when it said any."""

    def __init__(self, port: int, source: str, interval_s: float, stop: threading.Event) -> None:
        super().__init__(daemon=True)
        self.port, self.source, self.interval_s, self.stop = port, source, interval_s, stop
        self.admitted = threading.Event()
        self.reasons: list[str] = []

    def run(self) -> None:
        frame = struct.pack("<I", 4) + b"/abc" + struct.pack("<I", 1 << 20) + b"\0" * (1 << 20)
        sock, first = connect_from(self.port, self.source)
        with sock:
            if first is None or first.destination != "__handshake":
                return
            self.admitted.set()
            sock.settimeout(self.interval_s)
            decoder = FrameDecoder()
            for index in range(len(frame)):
                if self.stop.is_set():
                    return
                try:
                    sock.send(frame[index : index + 1])
                    data = sock.recv(65536)  # waits out the interval unless the endpoint says something
                except socket.timeout:
                    continue
                except OSError:
                    return
                if not data:
                    return
                self.reasons += [
                    json.loads(f.payload)["text"] for f in feed(decoder, data) if f.destination in ("__warn", "__error")
                ]


def test_a_fresh_client_is_served_while_slow_senders_hold_every_slot(roscore, ros_node, tmp_path: Path) -> None:
    endpoint = start_endpoint(roscore, tmp_path, "--max-clients", "8")
    stop = threading.Event()
    senders = [SlowSender(endpoint.port, f"127.0.0.{10 + index % 4}", 0.25, stop) for index in range(12)]
    newcomers: list[socket.socket] = []
    try:
        with RawConnection(endpoint.port) as steady:  # a client between whole frames uses its slot
            for sender in senders:
                sender.start()
            wait_for(lambda: sum(sender.admitted.is_set() for sender in senders) == 7, 10, "every slot held")
            time.sleep(FRAME_GRACE_S + 0.5)  # the senders' frames past the grace
            for _ in range(5):  # each stays, so the next needs room made again
                sock, frame = connect_from(endpoint.port, "127.0.0.50")
                newcomers.append(sock)
                assert frame is not None and frame.destination == "__handshake", frame
                steady.sync()
            stop.set()
            for sender in senders:
                sender.join(10)
            made_room = [
                reason
                for sender in senders
                for reason in sender.reasons
                if "closed to make room for a new client" in reason and "--max-clients" in reason
            ]
            assert len(made_room) >= 5, [sender.reasons for sender in senders]
            steady.sync()
            assert not steady.errors(), steady.summary()
    finally:
        stop.set()
        for sock in newcomers:
            sock.close()
        endpoint.stop()


class ReconnectingSlowSender(threading.Thread):
    """A slow-loris client from `source` that comes back at once whenever it is refused or closed, until stopped: a
    frame that never ends, a byte every `interval_s`. `closed_to_make_room` counts the times it was evicted."""

    def __init__(self, port: int, source: str, interval_s: float, stop: threading.Event) -> None:
        super().__init__(daemon=True)
        self.port, self.source, self.interval_s, self.stop = port, source, interval_s, stop
        self.closed_to_make_room = 0
        self.came_back = threading.Event()  # served again after the endpoint closed it
        self._closed_once = False

    def run(self) -> None:
        header = struct.pack("<I", 4) + b"/abc" + struct.pack("<I", 1 << 20)
        while not self.stop.is_set():
            try:
                sock, first = connect_from(self.port, self.source)
            except OSError:
                continue
            with sock:
                if first is None or first.destination != "__handshake":
                    self.stop.wait(0.01)
                    continue
                if self._closed_once:
                    self.came_back.set()
                sock.settimeout(self.interval_s)
                for index in range(10_000):
                    if self.stop.is_set():
                        return
                    try:
                        sock.send(header[index : index + 1] if index < len(header) else b"\0")
                        data = sock.recv(65536)
                    except socket.timeout:
                        continue
                    except OSError:
                        break
                    if not data or b"closing the connection" in data:
                        self.closed_to_make_room += b"closed to make room" in data
                        self._closed_once = True
                        break


def test_a_fresh_client_is_served_while_slow_senders_come_back_at_once(roscore, ros_node, tmp_path: Path) -> None:
    # Twelve slow senders for eight slots: the four turned away come back at once and, once the frames held pass
    # the grace, make room for themselves. Left to do so, they would keep every slot too young to judge, and a
    # fresh client would be refused (most of the time).
    endpoint = start_endpoint(roscore, tmp_path, "--max-clients", "8")
    stop = threading.Event()
    senders = [ReconnectingSlowSender(endpoint.port, f"127.0.0.{10 + index % 4}", 0.25, stop) for index in range(12)]
    newcomers: list[socket.socket] = []
    try:
        for sender in senders:
            sender.start()
        time.sleep(3 * FRAME_GRACE_S)  # the frames held past the grace: the senders turned away make room
        for _ in range(5):  # each newcomer stays, so the next needs room made again
            sock, frame = connect_from(endpoint.port, "127.0.0.50")
            newcomers.append(sock)
            assert frame is not None and frame.destination == "__handshake", frame
            time.sleep(0.2)
        assert sum(sender.closed_to_make_room for sender in senders) >= 5
    finally:
        stop.set()
        for sender in senders:
            sender.join(10)
        for sock in newcomers:
            sock.close()
        endpoint.stop()


def test_a_fresh_client_is_served_right_after_slow_senders_missed_their_deadline_and_came_back(
    roscore, ros_node, tmp_path: Path
) -> None:
    # As many slow senders as slots: --frame-timeout closes them all at once, and they come back at once, each too
    # young to judge. Their addresses missed a deadline a moment ago: the newcomer from elsewhere is served.
    endpoint = start_endpoint(roscore, tmp_path, "--max-clients", "4", "--frame-timeout", "2")
    stop = threading.Event()
    senders = [ReconnectingSlowSender(endpoint.port, f"127.0.0.{10 + index}", 0.25, stop) for index in range(4)]
    try:
        for sender in senders:
            sender.start()
        wait_for(lambda: all(sender.came_back.is_set() for sender in senders), 20, "every sender back")
        sock, frame = connect_from(endpoint.port, "127.0.0.50")
        sock.close()
        assert frame is not None and frame.destination == "__handshake", frame
    finally:
        stop.set()
        for sender in senders:
            sender.join(10)
        endpoint.stop()


def test_registrations_past_the_limits_are_refused_and_the_client_stays(roscore, ros_node, tmp_path: Path) -> None:
    endpoint = start_endpoint(
        roscore, tmp_path, "--max-registrations-per-client", "5", "--max-registrations", "8", "--publisher-grace", "0"
    )
    try:
        topics = [unique("limited") for _ in range(6)]
        with RawConnection(endpoint.port) as subscriber, RawConnection(endpoint.port) as publisher:
            for topic in topics:
                subscriber.subscribe(topic, "std_msgs/String")
            subscriber.expect_error("__subscribe", topics[5], "--max-registrations-per-client")
            subscriber.subscribe(topics[0], "std_msgs/String")  # one it has already: not a new registration
            subscriber.sync()
            assert len(subscriber.errors()) == 1

            published = [unique("limited_pub") for _ in range(4)]
            for topic in published:
                publisher.register_publisher(topic, "std_msgs/String")
            publisher.expect_error("__publish", published[3], "--max-registrations")
            publisher.sync()
            assert len(publisher.errors()) == 1
            subscriber.close()
            wait_for(lambda: _registers(publisher, published[3]), 10, "room once the subscriber left")
    finally:
        endpoint.stop()


def _registers(client: RawConnection, topic: str) -> bool:
    before = len(client.errors())
    client.register_publisher(topic, "std_msgs/String")
    client.sync()
    return len(client.errors()) == before


def test_a_registration_flood_is_bounded_and_released_when_the_client_leaves(roscore, ros_node, tmp_path: Path) -> None:
    endpoint = start_endpoint(roscore, tmp_path, "--publisher-grace", "0", name="flood_endpoint")
    try:
        settled(roscore, "/flood_endpoint")
        baseline = figures(endpoint.pid)
        with RawConnection(endpoint.port) as flood:
            for index in range(300):
                flood.register_publisher(unique(f"flood{index}"), "std_msgs/String")
            flood.sync(timeout=60)
            refused = [text for text in flood.errors() if "--max-registrations-per-client" in text]
            assert len(refused) == 300 - 256
            during = figures(endpoint.pid)
            print(f"{baseline} before, {during} with 256 publishers")
            assert during.threads <= baseline.threads + 256 + 8  # a pump per publisher, the client's reader, writer
        wait_for(
            lambda: (
                figures(endpoint.pid).threads <= baseline.threads
                and figures(endpoint.pid).descriptors <= baseline.descriptors
            ),
            20,
            f"back to {baseline}",
        )
    finally:
        endpoint.stop()


def test_a_client_that_never_reads_its_answers_costs_a_bounded_amount(roscore, ros_node, tmp_path: Path) -> None:
    # A long-shut receive window would pass the default --dead-peer-timeout (10 s), after which Linux gives the
    # client up as documented (TCP_USER_TIMEOUT counts window probes): the bound on memory is what is tested here.
    endpoint = start_endpoint(roscore, tmp_path, "--dead-peer-timeout", "60", name="unread_endpoint")
    try:
        settled(roscore, "/unread_endpoint")
        with RawConnection(endpoint.port, rcvbuf=4096) as silent, RawConnection(endpoint.port) as good:
            for index in range(200):  # a graph whose topic list is some 40 kB
                good.register_publisher(unique(f"answer_size_{index}_" + "x" * 160), "std_msgs/String")
            good.sync()
            before = figures(endpoint.pid).rss_mib
            query = protocol.encode_syscommand("__topic_list", {}) * 50
            deadline = time.monotonic() + 15
            for _ in range(250):  # 12,500 answers of some 40 kB each (500 MB), never read
                silent.send(query)
                time.sleep(0.02)
                if time.monotonic() > deadline:
                    break
            good.sync()  # everyone else is still served
            grown = figures(endpoint.pid).rss_mib - before
            print(f"endpoint RSS grew {grown:.1f} MiB")
            assert grown < 32
            silent.sock.settimeout(10)
            silent.sync(timeout=30)  # and the silent one, once it reads
    finally:
        endpoint.stop()


pytestmark = [pytest.mark.lane("endpoint", on=("noetic",)), pytest.mark.timeout(180)]
