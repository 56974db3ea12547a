"""The two far ends of tests/integration/test_bridge_across_machines.py, each run inside its own network namespace
(`ip netns exec NS python -m tests.integration.netns_peers ROLE ...`). Each prints one line per thing that worked,
`ok <what>`, and goes on serving its peer until it is stopped, or its deadline.

- `ros`: a rospy node on the master's host. It publishes /far/from_ros (std_msgs/String), waits for
  /far/to_ros, serves /far/ros_echo (std_srvs/SetBool: success = data) and calls /far/client_echo, a service the
  client implements through the endpoint.
- `client HOST PORT`: an endpoint client with no rospy (as Unity is): the mirror image of the above. It prints
  each `__error` it is sent as `error <text>`.
- `port HOST PORT TARGET_HOST TARGET_PORT`: what `docker run -p` puts on the container's host (docker-proxy): a TCP
  relay from HOST:PORT to the container's TARGET_HOST:TARGET_PORT, closing a connection the container refuses
  (`refused <address>`). Prints `ok listening` once it listens.
- `diagnostics`: a rospy node printing, for each /diagnostics array, `diagnostics <n>:` and the names of its
  warnings about links to ROS peers (bridge.ros.peer_links), `|`-separated.
"""

from __future__ import annotations

import contextlib
import socket
import struct
import sys
import threading
import time

DEADLINE_S = 40.0
FROM_ROS, TO_ROS = "/far/from_ros", "/far/to_ros"
ROS_ECHO, CLIENT_ECHO = "/far/ros_echo", "/far/client_echo"


def _string(text: str) -> bytes:
    data = text.encode()
    return struct.pack("<I", len(data)) + data


def _unstring(payload: bytes) -> str:
    (length,) = struct.unpack_from("<I", payload)
    return payload[4 : 4 + length].decode()


def _set_bool_response(success: bool, message: str) -> bytes:
    return struct.pack("<B", success) + _string(message)


def _say(what: str) -> None:
    print(f"ok {what}", flush=True)


def ros_side() -> int:
    import rospy
    from std_msgs.msg import String
    from std_srvs.srv import SetBool, SetBoolResponse

    rospy.init_node("far_ros_peer", disable_signals=True)
    heard = threading.Event()

    def on_message(message: String) -> None:
        if message.data == "hello from the client" and not heard.is_set():
            heard.set()
            _say("ros heard the client")

    rospy.Subscriber(TO_ROS, String, on_message)
    rospy.Service(ROS_ECHO, SetBool, lambda request: SetBoolResponse(request.data, "answered by ros"))
    publisher = rospy.Publisher(FROM_ROS, String, queue_size=10)
    called = False
    deadline = time.monotonic() + DEADLINE_S
    while time.monotonic() < deadline and not rospy.is_shutdown():
        publisher.publish(String("hello from ros"))
        if not called:
            try:
                rospy.wait_for_service(CLIENT_ECHO, timeout=0.1)
                answer = rospy.ServiceProxy(CLIENT_ECHO, SetBool)(True)
            except rospy.ROSException:
                answer = None
            if answer is not None and answer.success and answer.message == "answered by the client":
                called = True
                _say("ros called the client's service")
        time.sleep(0.1)
    return 0


def client_side(host: str, port: int) -> int:
    from bridge.client import TcpClient

    client = TcpClient(host, port, on_error=lambda text: print(f"error {text}", flush=True)).connect(timeout=10.0)
    _say(f"client connected to {host}:{port}")
    heard = threading.Event()
    client.subscribe(FROM_ROS, "std_msgs/String", lambda payload: heard.set())
    client.implement_service(
        CLIENT_ECHO, "std_srvs/SetBool", lambda _: _set_bool_response(True, "answered by the client")
    )
    client.register_publisher(TO_ROS, "std_msgs/String")
    client.register_ros_service(ROS_ECHO, "std_srvs/SetBool")
    deadline = time.monotonic() + DEADLINE_S
    called = said_heard = False
    while time.monotonic() < deadline:
        client.publish(TO_ROS, _string("hello from the client"))
        if not called:
            try:
                response = client.call_service(ROS_ECHO, struct.pack("<B", 1), timeout=1.0)
            except Exception:  # noqa: BLE001 - not offered yet, or not reachable yet: try again until the deadline
                response = b""
            if response[:1] == b"\x01" and _unstring(response[1:]) == "answered by ros":
                called = True
                _say("client called the ros service")
        if heard.wait(0.1) and not said_heard:
            said_heard = True
            _say("client heard ros")
    client.close()
    return 0


def diagnostics_side() -> int:
    import rospy
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

    rospy.init_node("far_diagnostics", disable_signals=True)
    arrays = iter(range(1, 1_000_000))

    def on_array(array: DiagnosticArray) -> None:
        links = [s.name for s in array.status if s.level == DiagnosticStatus.WARN and ": link " in s.name]
        print(f"diagnostics {next(arrays)}: {' | '.join(sorted(links))}", flush=True)

    rospy.Subscriber("/diagnostics", DiagnosticArray, on_array)
    time.sleep(DEADLINE_S)
    return 0


def _pipe(source: socket.socket, target: socket.socket) -> None:
    with contextlib.suppress(OSError):
        while True:
            data = source.recv(65536)
            if not data:
                break
            target.sendall(data)
    with contextlib.suppress(OSError):
        target.shutdown(socket.SHUT_WR)


def published_port(host: str, port: int, target: tuple[str, int]) -> int:
    listener = socket.create_server((host, port))
    listener.settimeout(1.0)
    _say("listening")
    deadline = time.monotonic() + DEADLINE_S
    while time.monotonic() < deadline:
        try:
            outside, address = listener.accept()
        except socket.timeout:
            continue
        try:
            inside = socket.create_connection(target, timeout=5.0)
        except OSError as error:
            print(f"refused {address[0]}:{address[1]}: {error}", flush=True)
            outside.close()
            continue
        for source, sink in ((outside, inside), (inside, outside)):
            threading.Thread(target=_pipe, args=(source, sink), daemon=True).start()
    return 0


def main(argv: list[str]) -> int:
    if argv[:1] == ["ros"]:
        return ros_side()
    if argv[:1] == ["client"] and len(argv) == 3:
        return client_side(argv[1], int(argv[2]))
    if argv[:1] == ["port"] and len(argv) == 5:
        return published_port(argv[1], int(argv[2]), (argv[3], int(argv[4])))
    if argv[:1] == ["diagnostics"]:
        return diagnostics_side()
    usage = "ros | client HOST PORT | port HOST PORT TARGET_HOST TARGET_PORT | diagnostics"
    print(f"usage: python -m tests.integration.netns_peers {usage}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
