"""Managed processes for demos, trials and tests: a roscore on a free port with its own ROS_HOME/ROS_LOG_DIR,
and node subprocesses in their own process groups, always stopped by PID (SIGINT, then SIGKILL).

A `prefix` (e.g. `ip netns exec NAME`) runs a process inside a network namespace; `ip netns exec` execs the
command, so the PID is still the process's own.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import xmlrpc.client
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TypeVar

from sim.errors import SimError

__all__ = [
    "REPO",
    "PYTHON",
    "ProcessError",
    "pid_alive",
    "subscribers_written",
    "writes_to",
    "free_port",
    "wait_for",
    "kill_process",
    "ros_environment",
    "ManagedProcess",
    "OUTPUT_TAIL_CHARS",
    "output_tail",
    "RosCore",
    "EndpointProcess",
    "endpoint_ports",
    "start_recorder",
    "stop_recorder",
    "plain_env",
]

REPO = Path(__file__).resolve().parents[1]
PYTHON = sys.executable

T = TypeVar("T")


class ProcessError(SimError, RuntimeError):
    """A managed process that did not start, or exited before it was ready."""


def free_port(host: str = "127.0.0.1") -> int:
    with socket.socket() as sock:
        sock.bind((host, 0))
        return sock.getsockname()[1]


def wait_for(predicate: Callable[[], T], timeout: float, what: str, interval: float = 0.02) -> T:
    """Poll `predicate` until it returns something truthy (returned) or `timeout` s pass (TimeoutError)."""
    deadline = time.monotonic() + timeout
    while True:
        result = predicate()
        if result:
            return result
        if time.monotonic() > deadline:
            raise TimeoutError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(interval)


def kill_process(process: subprocess.Popen, timeout: float = 5.0, first_signal: int = signal.SIGINT) -> None:
    """Signal the process group (SIGINT by default), then SIGKILL it if it has not gone after `timeout`."""
    if process.poll() is not None:
        return
    try:
        os.killpg(process.pid, first_signal)
        process.wait(timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait(timeout)
    except ProcessLookupError:
        pass


def ros_environment(master_uri: str, home: Path, host: str = "127.0.0.1") -> dict[str, str]:
    """The environment of every ROS process of one session: its master, its own ROS_HOME and log dir."""
    env = dict(os.environ)
    env.update(
        ROS_MASTER_URI=master_uri,
        ROS_HOME=str(home / "ros_home"),
        ROS_LOG_DIR=str(home / "log"),
        ROS_HOSTNAME=host,
        PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])),
        PYTHONUNBUFFERED="1",
    )
    env.pop("ROS_IP", None)
    return env


# How much of a failed process's output an error shows: its last lines, where the reason usually is.
OUTPUT_TAIL_CHARS = 3000


def output_tail(process: ManagedProcess) -> str:
    return process.output()[-OUTPUT_TAIL_CHARS:]


class ManagedProcess:
    """A subprocess in its own process group, output captured to a log file."""

    def __init__(
        self,
        args: Sequence[str],
        env: dict[str, str],
        log_dir: Path,
        name: str,
        prefix: Sequence[str] = (),
    ) -> None:
        log_dir.mkdir(parents=True, exist_ok=True)
        self.name = name
        self.log_path = log_dir / f"{name}-{time.monotonic_ns()}.log"
        with open(self.log_path, "wb") as log_file:
            self.process = subprocess.Popen(
                [*prefix, *args],
                env=env,
                cwd=REPO,
                stdout=log_file,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                start_new_session=True,
            )

    @property
    def pid(self) -> int:
        return self.process.pid

    def output(self) -> str:
        return self.log_path.read_text(errors="replace")

    def wait_for_output(self, text: str, timeout: float = 30.0) -> str:
        def seen() -> bool:
            output = self.output()
            if text in output:
                return True
            if self.process.poll() is not None:
                raise ProcessError(
                    f"{self.name} exited ({self.process.returncode}) before printing {text!r}:\n{output_tail(self)}"
                )
            return False

        wait_for(seen, timeout, f"{text!r} from {self.name}")
        return self.output()

    def wait(self, timeout: float) -> int:
        try:
            return self.process.wait(timeout)
        except subprocess.TimeoutExpired:
            raise ProcessError(f"{self.name} still running after {timeout} s:\n{output_tail(self)}") from None

    def stop(self, timeout: float = 5.0) -> int | None:
        kill_process(self.process, timeout)
        return self.process.returncode


class _QuickTransport(xmlrpc.client.Transport):
    """An XML-RPC transport that gives up after a second."""

    def make_connection(self, host: Any) -> Any:
        connection = super().make_connection(host)
        connection.timeout = 1.0
        return connection


def subscribers_written(node_uri: str, topic: str, caller_id: str = "/probe") -> set[str]:
    """The nodes that the ROS node at `node_uri` writes `topic` to (its getBusInfo; none when it does not answer).
    Only the publisher knows: a rospy subscriber counts a publisher as connected before it has even opened the
    socket, and what is published until the publisher takes the connection is lost."""
    try:
        proxy: Any = xmlrpc.client.ServerProxy(node_uri, transport=_QuickTransport())
        code, _, bus_info = proxy.getBusInfo(caller_id)
    except (OSError, xmlrpc.client.Error, ValueError):
        return set()
    # entries: [connection id, the other end (a subscriber's caller id), direction, transport, topic, ...]
    return {entry[1] for entry in bus_info if entry[2] == "o" and entry[4] == topic} if code == 1 else set()


def writes_to(node_uri: str, topic: str, caller_id: str) -> bool:
    """Whether the ROS node at `node_uri` writes `topic` to the node `caller_id` (see subscribers_written)."""
    return caller_id in subscribers_written(node_uri, topic, caller_id)


def pid_alive(pid: int) -> bool:
    """Whether a process `pid` exists (another user's counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _stop_pid(pid: int, timeout: float) -> None:
    """SIGTERM to a process that is not our child, then SIGKILL if it is still there after `timeout`."""
    deadline = time.monotonic() + timeout
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.kill(pid, sig)
        except (ProcessLookupError, PermissionError):
            return
        while time.monotonic() < deadline:
            if not pid_alive(pid):
                return
            time.sleep(0.05)
        deadline = time.monotonic() + 1.0


class RosCore(ManagedProcess):
    """`roscore -p <port>` with its own ROS_HOME/ROS_LOG_DIR in a temp dir; `env` is for every process of it.

    The dir (the logs of roscore and of every node of the session) is removed on `stop` unless it was given
    (`tmp`) or `keep_logs` is asked; `remove_tmp` overrides that, e.g. for a master restarted in the same dir."""

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int | None = None,
        prefix: Sequence[str] = (),
        tmp: Path | None = None,
        remove_tmp: bool | None = None,
    ) -> None:
        self.remove_tmp = tmp is None if remove_tmp is None else remove_tmp
        self.tmp = tmp or Path(tempfile.mkdtemp(prefix="roscore-"))
        self.host = host
        self.port = port or free_port()
        self.uri = f"http://{host}:{self.port}/"
        self.env = ros_environment(self.uri, self.tmp, host)
        super().__init__(["roscore", "-p", str(self.port)], self.env, self.tmp, "roscore", prefix)
        try:
            # roscore prints this once rosout is up, i.e. when the master is fully usable (also inside a netns).
            self.wait_for_output("started core service [/rosout]", timeout=30)
        except BaseException:
            self.stop()
            raise

    def stop(self, timeout: float = 5.0, keep_logs: bool = False) -> int | None:
        # roslaunch may not take rosmaster down with it when stopped right after start: it is then stopped by its pid.
        master_pid = self._master_pid()
        returncode = super().stop(timeout)
        if master_pid is not None:
            _stop_pid(master_pid, timeout)
        if self.remove_tmp and not keep_logs:
            shutil.rmtree(self.tmp, ignore_errors=True)
        return returncode

    def _master_pid(self) -> int | None:
        """rosmaster's pid, as the master says (None when it does not answer within a second)."""
        try:
            proxy: Any = xmlrpc.client.ServerProxy(self.uri, transport=_QuickTransport())
            code, _, pid = proxy.getPid("/stopping")
        except (OSError, xmlrpc.client.Error):
            return None
        return int(pid) if code == 1 else None

    def subscribers(self, topic: str) -> list[str]:
        """Node names subscribed to `topic`, as the master sees them."""
        state: Any = xmlrpc.client.ServerProxy(self.uri).getSystemState("/probe")
        _, _, (_, subscribers, _) = state
        return next((nodes for name, nodes in subscribers if name == topic), [])

    def publishers(self, topic: str) -> list[str]:
        """Node names publishing `topic`, as the master sees them."""
        state: Any = xmlrpc.client.ServerProxy(self.uri).getSystemState("/probe")
        _, _, (publishers, _, _) = state
        return next((nodes for name, nodes in publishers if name == topic), [])


class EndpointProcess(ManagedProcess):
    """`python -m bridge --tcp-port 0` (a free port), returned once it listens; `port` is the port it reports, and
    `websocket_port` the WebSocket port when `extra` asks for one (--websocket-port). `host`: the address it listens
    on (default: the endpoint's own default)."""

    def __init__(
        self,
        env: dict[str, str],
        log_dir: Path,
        name: str = "endpoint",
        extra: Sequence[str] = (),
        host: str | None = None,
        prefix: Sequence[str] = (),
    ) -> None:
        address = [] if host is None else ["--tcp-ip", host]
        super().__init__(
            [PYTHON, "-m", "bridge", *address, "--tcp-port", "0", "--node-name", name, *extra],
            env,
            log_dir,
            name,
            prefix,
        )
        websocket = "--websocket-port" in extra
        try:
            self.port, self.websocket_port = endpoint_ports(self, websocket)
        except BaseException:
            self.stop()
            raise


def endpoint_ports(endpoint: ManagedProcess, websocket: bool) -> tuple[int, int | None]:
    """The TCP port a starting endpoint process reports once it listens, and its WebSocket port when it was asked
    for one (None otherwise)."""
    websocket_line = "WebSocket clients: ws://"
    lines = endpoint.wait_for_output(websocket_line if websocket else "listening on", timeout=30).splitlines()
    port = int(next(line for line in lines if "listening on" in line).rsplit(":", 1)[1])
    if not websocket:
        return port, None
    return port, int(next(line for line in lines if websocket_line in line).rstrip("/").rsplit(":", 1)[1])


def start_recorder(
    bag: Path, topics: Sequence[str], node: str, env: dict[str, str], log_dir: Path, prefix: Sequence[str] = ()
) -> ManagedProcess:
    """`rosbag record` of `topics` into `bag` as node `node`. Its output is line-buffered, so "Recording to" shows
    as soon as it records: wait for that with `wait_for_output`."""
    bag.parent.mkdir(parents=True, exist_ok=True)
    return ManagedProcess(
        ["stdbuf", "-oL", "-eL", "rosbag", "record", "-O", str(bag), *topics, f"__name:={node}"],
        env,
        log_dir,
        "rosbag",
        prefix,
    )


def stop_recorder(recorder: ManagedProcess, bag: Path) -> None:
    """SIGINT lets rosbag close the bag; its C++ recorder renames .bag.active to .bag as the last thing it does."""
    recorder.stop(timeout=10)
    active = bag.with_name(bag.name + ".active")
    with contextlib.suppress(TimeoutError):  # a bag left .active is the caller's to report (it finds no bag)
        wait_for(lambda: bag.exists() or not active.exists(), 10, f"rosbag to close {bag}", interval=0.05)


def plain_env() -> dict[str, str]:
    """The no-ROS processes' environment: ours, with the repository importable."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))
    return env
