"""Calls of a ROS service with request bytes, answered with response bytes, every step under the call's deadline:
TCPROS spoken here, since rospy's ServiceProxy can wait for an answer forever.
"""

from __future__ import annotations

import socket
import struct
import threading
import time
import weakref
from typing import Any

import rosgraph
import rosgraph.network
import rospy
import rospy.impl.tcpros_pubsub

from bridge.ros.master import MASTER_TIMEOUT_S, MasterError, MasterRefused, call_master
from bridge.ros.raw_types import RosError

_U32 = struct.Struct("<I")

__all__ = ["OPENING_AT_ONCE", "SERVICE_POLL_S", "RawServiceProxy"]

# A ROS service call looks this often whether its client has gone, and whether the service has been advertised.
SERVICE_POLL_S = 0.2
# Connections opened to one service at once, by all clients' proxies. rospy's service servers listen with a backlog
# of 5: a burst of connections past it has SYNs dropped and waits for their retransmission, 1 s and then 3 s (a
# burst of 64 calls to a rospy service answering in 1 s had its last answers after 3 s). Opening is fast: the rest
# waits little.
OPENING_AT_ONCE = 4


class _Service:
    """What every proxy of one service shares: the gate of the connections opening, and the look-up in flight."""

    def __init__(self) -> None:
        self.opening = threading.BoundedSemaphore(OPENING_AT_ONCE)
        self.asking_lock = threading.Lock()
        self.asking: _Asking | None = None


# By service name, for as long as a proxy of it lives (each holds its own)
_SERVICES: weakref.WeakValueDictionary[str, _Service] = weakref.WeakValueDictionary()
_SERVICES_LOCK = threading.Lock()


def _shared(service: str) -> _Service:
    with _SERVICES_LOCK:
        shared = _SERVICES.get(service)
        if shared is None:
            shared = _SERVICES[service] = _Service()
        return shared


class _Abandoned(Exception):
    """The call's client has gone: nobody waits for the answer any more."""


class RawServiceProxy:
    """Calls of one ROS service with request bytes, answered with response bytes; every call ends by its deadline.

    rospy's ServiceProxy waits for an answer with no limit (its timeout bounds only the wait for the service to
    appear), on a socket the caller cannot close: a service that never answers holds the calling thread forever.
    This speaks TCPROS itself (one connection per call, as rospy's non-persistent proxy does), with the deadline on
    every step, and gives up early when `abandoned` is set (the client left).
    """

    def __init__(self, raw_class: Any, service: str, max_response_bytes: int) -> None:
        self.service = service
        self.service_type: str = raw_class._type
        self._md5sum: str = raw_class._md5sum
        self._max_response_bytes = max_response_bytes
        self._shared = _shared(service)

    def call(self, request: bytes, timeout: float, abandoned: threading.Event, asked_at: float | None = None) -> bytes:
        """The response's bytes; RosError when the service is missing, fails, or does not answer within `timeout`
        seconds (the look-up included) of `asked_at` (monotonic; default now): a call that waited for a worker has
        had part of its time already."""
        deadline = (time.monotonic() if asked_at is None else asked_at) + timeout
        try:
            sock, header = self._open(self._look_up(deadline, timeout, abandoned), deadline, abandoned)
            with sock:
                if "error" in header:
                    raise RosError(f"service {self.service} refused the call: {header['error']}")
                sock.sendall(_U32.pack(len(request)) + request)
                ok = _receive(sock, 1, deadline, abandoned)[0]
                size = _U32.unpack(_receive(sock, 4, deadline, abandoned))[0]
                if size > self._max_response_bytes:
                    raise RosError(
                        f"service {self.service} answered with {size} bytes, more than the "
                        f"{self._max_response_bytes} a frame may carry"
                    )
                body = _receive(sock, size, deadline, abandoned)
        except socket.timeout:
            raise RosError(f"service {self.service} did not answer within {timeout:g} s") from None
        except _Abandoned:
            raise RosError(f"service {self.service}: the call's client has gone") from None
        except (OSError, ValueError, rosgraph.network.ROSHandshakeException) as error:
            raise RosError(f"service {self.service} could not be called: {error}") from None
        if not ok:
            raise RosError(f"service {self.service} failed: {body.decode('utf-8', 'replace')}")
        return body

    def _open(self, uri: str, deadline: float, abandoned: threading.Event) -> tuple[socket.socket, dict]:
        """A connection to the service and its answer to our connection header, opened when fewer than
        OPENING_AT_ONCE to the service are: a burst of calls must not overflow the server's backlog (see there)."""
        while not self._shared.opening.acquire(timeout=min(_remaining(deadline), SERVICE_POLL_S)):
            if abandoned.is_set():
                raise _Abandoned()
        try:
            sock = socket.create_connection(rospy.core.parse_rosrpc_uri(uri), timeout=_remaining(deadline))
            try:
                sock.sendall(
                    rosgraph.network.encode_ros_handshake_header(
                        {
                            "callerid": rospy.get_caller_id(),
                            "service": self.service,
                            "md5sum": self._md5sum,
                            "type": self.service_type,
                            "persistent": "0",
                        }
                    )
                )
                size = _U32.unpack(_receive(sock, 4, deadline, abandoned))[0]
                if size > 65536:
                    raise RosError(f"service {self.service} sent a connection header of {size} bytes")
                return sock, rosgraph.network.decode_ros_handshake_header(
                    _U32.pack(size) + _receive(sock, size, deadline, abandoned)
                )
            except BaseException:
                sock.close()
                raise
        finally:
            self._shared.opening.release()

    def _look_up(self, deadline: float, timeout: float, abandoned: threading.Event) -> str:
        """The service's rosrpc URI, waiting for it to be advertised until the deadline."""
        while True:
            try:
                return self._ask_master(deadline, abandoned)
            except MasterRefused:
                why = "is not available"  # not advertised (yet)
            except MasterError as error:
                why = f"could not be looked up: {error}"
            # The verdict is the master's answer, however late it came: a look-up that ended at or past the
            # deadline (a slow master, a loaded machine) says why, never "did not answer".
            remaining = deadline - time.monotonic()
            if remaining > 0 and abandoned.wait(min(SERVICE_POLL_S, remaining)):
                raise _Abandoned()
            if time.monotonic() >= deadline:
                raise RosError(f"service {self.service} {why} (waited {timeout:g} s)")

    def _ask_master(self, deadline: float, abandoned: threading.Event) -> str:
        """The master's answer to lookupService, or its MasterError. The calls of the service (every client's) share
        one question in flight: 64 calls to a missing one would ask 320 times a second, 5 each, as long as they wait."""
        shared = self._shared
        with shared.asking_lock:
            asking, ours = shared.asking, shared.asking is None
            if asking is None:
                asking = shared.asking = _Asking()
        if ours:
            try:
                asking.uri = call_master(
                    "lookupService",
                    rospy.get_caller_id(),
                    self.service,
                    timeout_s=max(0.01, min(MASTER_TIMEOUT_S, deadline - time.monotonic())),
                )
            except MasterError as error:
                # Its kind and text, not the error itself: its traceback holds the master's connection, and a
                # cycle through this frame would keep it open until the garbage collector runs.
                asking.failure = (type(error), str(error))
            finally:
                with shared.asking_lock:
                    shared.asking = None
                asking.answered.set()
        while not asking.answered.wait(min(SERVICE_POLL_S, max(0.0, deadline - time.monotonic()))):
            if abandoned.is_set():
                raise _Abandoned()
            if time.monotonic() >= deadline:  # a safety net: the question has its asker's deadline, no later than ours
                raise MasterError(f"the ROS master did not answer lookupService ({self.service}) in time")
        if asking.failure is not None:
            kind, text = asking.failure
            raise kind(text)
        assert asking.uri is not None
        return asking.uri


class _Asking:
    """A lookupService in flight, its answer for every call that waits for it."""

    def __init__(self) -> None:
        self.answered = threading.Event()
        self.uri: str | None = None
        self.failure: tuple[type[MasterError], str] | None = None


def _remaining(deadline: float) -> float:
    remaining = deadline - time.monotonic()
    if remaining <= 0:
        raise socket.timeout()
    return remaining


def _receive(sock: socket.socket, size: int, deadline: float, abandoned: threading.Event) -> bytes:
    """Exactly `size` bytes; socket.timeout at the deadline, _Abandoned as soon as the client has gone (looked at
    every SERVICE_POLL_S)."""
    data = bytearray()
    while len(data) < size:
        if abandoned.is_set():
            raise _Abandoned()
        sock.settimeout(min(_remaining(deadline), SERVICE_POLL_S))
        try:
            chunk = sock.recv(min(size - len(data), 1 << 20))
        except socket.timeout:
            continue
        if not chunk:
            raise ConnectionResetError("the service closed the connection")
        data += chunk
    return bytes(data)
