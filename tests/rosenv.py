"""Real ROS processes for tests: a roscore on a free port with its own ROS_HOME/ROS_LOG_DIR, and node subprocesses.

Every process is started in its own process group and killed by PID, so nothing outlives the test session.
"""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
import xmlrpc.client
from collections.abc import Sequence
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PYTHON = sys.executable


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def wait_for(predicate, timeout: float, what: str, interval: float = 0.02):
    deadline = time.monotonic() + timeout
    while True:
        result = predicate()
        if result:
            return result
        if time.monotonic() > deadline:
            raise TimeoutError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(interval)


class RosCore:
    """`roscore -p <port>` in a temp dir; `env` is the environment every ROS process of the session uses."""

    def __init__(self) -> None:
        self.tmp = Path(tempfile.mkdtemp(prefix="roscore-"))
        self.port = free_port()
        self.uri = f"http://127.0.0.1:{self.port}/"
        self.env = dict(os.environ)
        self.env.update(
            ROS_MASTER_URI=self.uri,
            ROS_HOME=str(self.tmp / "ros_home"),
            ROS_LOG_DIR=str(self.tmp / "log"),
            ROS_HOSTNAME="127.0.0.1",
            PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])),
            PYTHONUNBUFFERED="1",
        )
        self.env.pop("ROS_IP", None)
        self.process = subprocess.Popen(
            ["roscore", "-p", str(self.port)],
            env=self.env,
            stdout=open(self.tmp / "roscore.out", "wb"),
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        wait_for(self._master_up, 30, f"roscore on port {self.port}", interval=0.1)

    def _master_up(self) -> bool:
        if self.process.poll() is not None:
            raise RuntimeError(f"roscore exited: {(self.tmp / 'roscore.out').read_text()[-2000:]}")
        try:
            code, _, _ = xmlrpc.client.ServerProxy(self.uri).getSystemState("/probe")
            # rosout registers after the master; its presence means roscore is fully up.
            return code == 1 and self._has_rosout()
        except OSError:
            return False

    def _has_rosout(self) -> bool:
        code, _, uri = xmlrpc.client.ServerProxy(self.uri).lookupNode("/probe", "/rosout")
        return code == 1 and bool(uri)

    def stop(self) -> None:
        kill_process(self.process)


def kill_process(process: subprocess.Popen, timeout: float = 5.0) -> None:
    """SIGINT the process group, then SIGKILL it if it has not gone after `timeout`."""
    if process.poll() is None:
        try:
            os.killpg(process.pid, signal.SIGINT)
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait(timeout)
        except ProcessLookupError:
            pass


class NodeProcess:
    """A node (or any command) as a subprocess with the session's ROS environment; output captured to a file."""

    def __init__(self, args: Sequence[str], env: dict[str, str], log_dir: Path, name: str) -> None:
        self.log_path = log_dir / f"{name}-{time.monotonic_ns()}.log"
        self.process = subprocess.Popen(
            list(args),
            env=env,
            cwd=REPO,
            stdout=open(self.log_path, "wb"),
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )

    def output(self) -> str:
        return self.log_path.read_text(errors="replace")

    def wait_for_output(self, text: str, timeout: float = 30.0) -> str:
        def seen() -> bool:
            if self.process.poll() is not None and text not in self.output():
                raise RuntimeError(f"process exited ({self.process.returncode}) before printing {text!r}:\n{self.output()[-3000:]}")
            return text in self.output()

        wait_for(seen, timeout, f"{text!r} in {self.log_path.name}")
        return self.output()

    def stop(self, timeout: float = 5.0) -> int | None:
        kill_process(self.process, timeout)
        return self.process.returncode


class EndpointProcess(NodeProcess):
    """`python -m bridge --tcp-port 0` on the session's roscore; `port` is the port it reports."""

    def __init__(self, env: dict[str, str], log_dir: Path, name: str = "endpoint", extra: Sequence[str] = ()) -> None:
        super().__init__(
            [PYTHON, "-m", "bridge", "--tcp-port", "0", "--node-name", name, *extra], env, log_dir, name
        )
        text = self.wait_for_output("listening on", timeout=30)
        line = next(line for line in text.splitlines() if "listening on" in line)
        self.port = int(line.rsplit(":", 1)[1])
