"""chaos_bench's capacity and services phases (issue 52's hostile world), run beside CPU burners to starve the
endpoint: `.venv/bin/python -m bench.chaos_bench --only capacity services`, with e.g. three
`timeout 600 sh -c 'while :; do :; done' &` on two cores. Each prints its counts; the bench judges nothing.

  capacity   100 slow senders from 10 addresses for 64 slots, each back at once when refused or closed, while a
             fresh client from another address connects once a second (40 s; --quick 10 s): how many were
             served; --frame-timeout 10 ends the senders' frames together now and then
  services   every call of seven cases, ended (answer or __error) within --service-timeout (3 s) + 2 s, and the
             endpoint's threads back to their baseline after each case
"""

from __future__ import annotations

import json
import socket
import struct
import sys
import threading
import time
from collections.abc import Callable

from bridge import protocol
from bridge.protocol.framing import encode_frame, encode_syscommand
from measuring.frames import Frame, feed
from measuring.procfs import figures
from sim.processes import EndpointProcess, ManagedProcess, RosCore, wait_for

SERVICE_TIMEOUT_S = 3.0
ENDED_WITHIN_S = SERVICE_TIMEOUT_S + 2
TRIGGER = "std_srvs/Trigger"
MASTER_CONNECTIONS = 3  # threads of rospy's for the master's XML-RPC connections: not the endpoint's to release


# --- capacity ------------------------------------------------------------------------------------------------------


def _first_frame(port: int, source: str, timeout: float) -> Frame | None:
    """The first frame the endpoint sends a new connection from `source` (None: closed or silent); the connection is
    closed again."""
    with socket.socket() as sock:
        sock.bind((source, 0))
        sock.settimeout(timeout)
        try:
            sock.connect(("127.0.0.1", port))
            decoder = protocol.FrameDecoder()
            while True:
                data = sock.recv(65536)
                if not data:
                    return None
                frames = [frame for frame in feed(decoder, data) if isinstance(frame, Frame)]
                if frames:
                    return frames[0]
        except OSError:
            return None


def _slow_sender(port: int, source: str, stop: threading.Event) -> None:
    """A frame that never ends, a byte a second; back at once (10 ms) when refused or closed, until `stop`."""
    header = struct.pack("<I", 4) + b"/abc" + struct.pack("<I", 1 << 20)
    while not stop.is_set():
        try:
            sock = socket.create_connection(("127.0.0.1", port), timeout=1, source_address=(source, 0))
        except OSError:
            stop.wait(0.01)
            continue
        with sock:
            for index in range(3600):
                if stop.is_set():
                    return
                try:
                    sock.send(header[index : index + 1] if index < len(header) else b"\0")
                    if not sock.recv(65536):
                        break
                except socket.timeout:
                    continue
                except OSError:
                    break
        stop.wait(0.01)


def phase_capacity(endpoint: EndpointProcess, seconds: float) -> str:
    stop = threading.Event()
    senders = [
        threading.Thread(target=_slow_sender, args=(endpoint.port, f"127.0.0.{10 + index % 10}", stop), daemon=True)
        for index in range(100)
    ]
    for sender in senders:
        sender.start()
    refusals: list[str] = []
    probes = 0
    try:
        time.sleep(3)  # every slot held, and the frames held past their grace
        started = time.monotonic()
        while time.monotonic() - started < seconds:
            probes += 1
            frame = _first_frame(endpoint.port, "127.0.0.100", 10)
            if frame is None or frame.destination != "__handshake":
                refusals.append("no answer in 10 s" if frame is None else frame.payload.decode(errors="replace"))
            time.sleep(1)
    finally:
        stop.set()
        for sender in senders:
            sender.join(10)
    said = f"; refused: {refusals[:3]}" if refusals else ""
    return f"100 slow senders back at once for 64 slots; a fresh client: served {probes - len(refusals)}/{probes}{said}"


# --- services ------------------------------------------------------------------------------------------------------

SERVICES_NODE = """
import threading, time, rospy
from std_srvs.srv import Trigger, TriggerResponse
rospy.init_node("chaos_services", disable_signals=True)
never = threading.Event()
rospy.Service("/chaos/fast", Trigger, lambda request: TriggerResponse(True, "fast"))
rospy.Service("/chaos/slow", Trigger, lambda request: time.sleep(1.0) or TriggerResponse(True, "slow"))
rospy.Service("/chaos/hung", Trigger, lambda request: never.wait(600) or TriggerResponse(True, "late"))
print("ready", flush=True)
rospy.spin()
"""

# ROS callers of the client's service /chaos/unity, each printing how its call ended and after how long
CALLERS_NODE = """
import sys, threading, time, rospy
from std_srvs.srv import Trigger
rospy.init_node("chaos_callers", anonymous=True, disable_signals=True)
rospy.wait_for_service("/chaos/unity", 30)
def call():
    started = time.monotonic()
    try:
        rospy.ServiceProxy("/chaos/unity", Trigger)()
        print("ENDED answer", time.monotonic() - started, flush=True)
    except Exception:
        print("ENDED error", time.monotonic() - started, flush=True)
callers = [threading.Thread(target=call) for _ in range(int(sys.argv[1]))]
for caller in callers: caller.start()
for caller in callers: caller.join(120)
print("DONE", flush=True)
"""


class _Client:
    """A raw client from its own loopback address (the per-address limit is 16)."""

    made = 0

    def __init__(self, port: int) -> None:
        _Client.made += 1
        source = f"127.0.1.{_Client.made % 200 + 1}"
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=30, source_address=(source, 0))
        self._decoder = protocol.FrameDecoder()
        self._frames: list[Frame] = []

    def command(self, name: str, **params: object) -> None:
        self.sock.sendall(encode_syscommand(name, params))

    def call(self, service: str, srv_id: int) -> None:
        self.sock.sendall(encode_syscommand("__request", {"srv_id": srv_id}) + encode_frame(service, b""))

    def next_frame(self, deadline: float) -> Frame | None:
        while not self._frames:
            if time.monotonic() >= deadline:
                return None
            self.sock.settimeout(deadline - time.monotonic())
            try:
                data = self.sock.recv(65536)
            except (socket.timeout, OSError):
                return None
            if not data:
                return None
            self._frames += [frame for frame in feed(self._decoder, data) if isinstance(frame, Frame)]
        return self._frames.pop(0)

    def sync(self) -> None:
        self.command("__topic_list")
        deadline = time.monotonic() + 60
        while (frame := self.next_frame(deadline)) is not None and frame.destination != "__topic_list":
            pass

    def reset(self) -> None:
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        self.sock.close()


def _endings(client: _Client, asked: dict[int, float]) -> dict[int, float]:
    """srv_id: seconds from asking to its answer or __error, for the calls in `asked` that ended within 60 s."""
    ended: dict[int, float] = {}
    answering: int | None = None
    deadline = time.monotonic() + 60
    while len(ended) < len(asked) and (frame := client.next_frame(deadline)) is not None:
        if frame.destination in ("__response", "__error"):
            srv_id = json.loads(frame.payload).get("srv_id")
            if frame.destination == "__response":
                answering = srv_id
            elif srv_id in asked:
                ended[srv_id] = time.monotonic() - asked[srv_id]
        elif answering is not None:  # the response's body
            ended[answering] = time.monotonic() - asked[answering]
            answering = None
    return ended


def _storm(port: int, service: str, calls: int = 50) -> list[float | None]:
    client = _Client(port)
    client.command("__ros_service", topic=service, message_name=TRIGGER)
    client.sync()
    asked = {}
    for srv_id in range(calls):
        asked[srv_id] = time.monotonic()
        client.call(service, srv_id)
    ended = _endings(client, asked)
    client.sock.close()
    return [ended.get(srv_id) for srv_id in asked]


def _one_each(port: int) -> list[float | None]:
    clients = [_Client(port) for _ in range(50)]
    for client in clients:
        client.command("__ros_service", topic="/chaos/slow", message_name=TRIGGER)
        client.sync()
    results: list[float | None] = [None] * len(clients)

    def wait(index: int, asked: dict[int, float]) -> None:
        results[index] = _endings(clients[index], asked).get(index)

    waiters = []
    for index, client in enumerate(clients):
        asked = {index: time.monotonic()}
        client.call("/chaos/slow", index)
        waiters.append(threading.Thread(target=wait, args=(index, asked)))
        waiters[-1].start()
    for waiter in waiters:
        waiter.join()
    for client in clients:
        client.sock.close()
    return results


def _resets(port: int) -> list[float | None]:
    clients = [_Client(port) for _ in range(50)]
    for client in clients:
        client.command("__ros_service", topic="/chaos/slow", message_name=TRIGGER)
        client.sync()
    for index, client in enumerate(clients):
        client.call("/chaos/slow", index)
        client.reset()
    return []  # nobody is left to hear: only the threads tell


def _unity_callers(core: RosCore, port: int, callers: int, reset_mid_call: bool) -> list[float | None]:
    client = _Client(port)
    client.command("__unity_service", topic="/chaos/unity", message_name=TRIGGER)
    client.sync()
    process = ManagedProcess([sys.executable, "-c", CALLERS_NODE, str(callers)], core.env, core.tmp, "callers")
    try:
        if reset_mid_call:
            deadline = time.monotonic() + 60
            while (frame := client.next_frame(deadline)) is not None and frame.destination != "__request":
                pass
            client.reset()
        wait_for(lambda: "DONE" in process.output(), 120, "the ROS callers")
        ended: list[float | None] = [
            float(line.split()[2]) for line in process.output().splitlines() if line.startswith("ENDED")
        ]
    finally:
        process.stop()
        if not reset_mid_call:
            client.sock.close()
    return ended + [None] * (callers - len(ended))


def phase_services(core: RosCore, endpoint: EndpointProcess) -> list[str]:
    node = ManagedProcess([sys.executable, "-c", SERVICES_NODE], core.env, core.tmp, "chaos_services")
    try:
        wait_for(lambda: "ready" in node.output(), 60, "the services node")
        baseline = figures(endpoint.pid).threads
        cases: list[tuple[str, Callable[[], list[float | None]]]] = [
            ("a storm of 50 calls from one client", lambda: _storm(endpoint.port, "/chaos/fast")),
            ("the same, to a 1 s service", lambda: _storm(endpoint.port, "/chaos/slow")),
            ("one call from each of 50 clients, to a 1 s service", lambda: _one_each(endpoint.port)),
            ("a service that never answers", lambda: _storm(endpoint.port, "/chaos/hung", 1)),
            ("50 clients that reset right after calling", lambda: _resets(endpoint.port)),
            (
                "20 ROS callers of a Unity service never answered",
                lambda: _unity_callers(core, endpoint.port, 20, False),
            ),
            ("a Unity service client that resets mid-call", lambda: _unity_callers(core, endpoint.port, 1, True)),
        ]
        lines = []
        for name, run in cases:
            ended = run()
            in_time = sum(1 for took in ended if took is not None and took <= ENDED_WITHIN_S)
            slowest = max((took for took in ended if took is not None), default=0.0)
            try:
                wait_for(lambda: figures(endpoint.pid).threads <= baseline + MASTER_CONNECTIONS, 20, "threads back")
                threads = "back"
            except TimeoutError:
                threads = f"NOT back ({figures(endpoint.pid).threads}, baseline {baseline})"
            lines.append(
                f"{name}: {in_time}/{len(ended)} ended within {ENDED_WITHIN_S:g} s (slowest {slowest:.2f} s); "
                f"threads {threads}"
            )
        return lines
    finally:
        node.stop()
