"""The endpoint's services, both ways: ROS services a client calls (__ros_service, __request), and services a
client implements for ROS (__unity_service: ROS calls become __request frames, the client's __response the answer).
"""

from __future__ import annotations

import itertools
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from bridge import protocol
from bridge.bridged import Bridged, ClientRegistrations, made_for_client
from bridge.connection.session import ClientSession
from bridge.errors import RequestRefused
from bridge.protocol import RosService, ServiceRequest, ServiceResponse, UnityService
from bridge.ros.raw_types import RosError

__all__ = ["Services"]


@dataclass
class _ClientService:
    """A service a client implements, advertised on ROS."""

    service_type: str  # 'pkg/Service'
    handle: Any
    owner: ClientSession
    client_name: str  # the service as the client spells it


@dataclass
class _PendingCall:
    """A ROS call of a client's service, waiting for the client's __response."""

    owner: ClientSession
    service_type: str  # 'pkg/Service', to check the client's response
    done: threading.Event = field(default_factory=threading.Event)
    response: bytes | None = None
    failure: str | None = None


class Services:
    """Every bridged service, both ways. Registrations run on the clients' reader threads under the shared lock;
    calls of ROS services run on the calling client's workers, calls of clients' services on rospy's threads."""

    def __init__(self, bridged: Bridged) -> None:
        self._bridged = bridged
        self._ros = bridged.ros
        self._config = bridged.config
        self._lock = bridged.lock
        self._clients = bridged.clients
        self._client_services: dict[str, _ClientService] = {}
        self._pending: dict[int, _PendingCall] = {}
        self._srv_ids = itertools.count(1001)

    def count(self) -> int:
        """ROS objects the services hold: the clients' services advertised on ROS (a proxy holds none)."""
        return len(self._client_services)

    # --- ROS services a client calls --------------------------------------------------------------------------
    def register_ros_service(self, session: ClientSession, command: RosService) -> None:
        resolved = self._bridged.permitted(command.topic)
        raw = made_for_client(lambda: self._ros.service_type(command.message_name))
        proxy = self._ros.make_service_proxy(resolved, raw, self._config.max_payload_bytes)
        with self._lock:
            registrations = self._clients[session]
            # A proxy holds no ROS object: it counts for the client only.
            self._bridged.room(session, "__ros_service", resolved, command.topic in registrations.ros_services, False)
            registrations.ros_services[command.topic] = proxy

    def call_ros_service(self, session: ClientSession, request: ServiceRequest) -> None:
        srv_id = request.srv_id
        proxy = self._clients[session].ros_services.get(request.service)
        if proxy is None:
            raise RequestRefused(
                f"__request {srv_id}: service {request.service!r} was not registered with __ros_service; "
                "this call will not complete",
                srv_id,
            )
        problem = self._bridged.payload_problem(proxy.service_type, request.payload, "request")
        if problem is not None:
            raise RequestRefused(
                f"__request {srv_id}: service {request.service}: {problem}; not sent to ROS, this call will not "
                "complete",
                srv_id,
            )
        timeout = self._config.service_timeout_s
        # the deadline runs from here, not from when the call finds room (bridge.connection.calls)
        asked_at = time.monotonic()

        def call() -> None:
            if time.monotonic() - asked_at >= timeout:
                session.send_error(
                    f"__request {srv_id}: service {request.service} not called: the call waited {timeout:g} s, its "
                    "whole --service-timeout, for room among the calls in flight (--call-workers, --max-clients); "
                    "this call will not complete",
                    srv_id,
                )
                return
            try:
                response = proxy.call(request.payload, timeout, session.gone, asked_at)
            except RosError as error:
                session.send_error(f"__request {srv_id}: {error}; this call will not complete", srv_id)
                return
            session.send(protocol.encode(ServiceResponse(srv_id, request.service, response)), droppable=False)

        session.run_call(f"__request {srv_id} ({request.service})", call, srv_id)

    # --- services a client implements -------------------------------------------------------------------------
    def register_client_service(self, session: ClientSession, command: UnityService) -> None:
        resolved = self._bridged.permitted(command.topic)
        raw = made_for_client(lambda: self._ros.service_type(command.message_name))
        with self._lock:
            existing = self._client_services.get(resolved)
            if existing is not None and existing.service_type == command.message_name:
                # Re-registration (typically a reconnect): the newest client answers from now on.
                self._bridged.room(
                    session, "__unity_service", resolved, resolved in self._clients[session].unity_services, False
                )
                previous = self._clients.get(existing.owner)
                if previous is not None:
                    previous.unity_services.discard(resolved)
                existing.owner = session
                existing.client_name = command.topic
                self._clients[session].unity_services.add(resolved)
                return
            if existing is not None:
                raise RequestRefused(
                    f"__unity_service: service {resolved} is already provided as {existing.service_type}, "
                    f"not {command.message_name}"
                )
            self._bridged.room(session, "__unity_service", resolved, False, True)
            handle = made_for_client(
                lambda: self._ros.make_service(
                    resolved, raw, lambda request: self.call_client_service(resolved, request)
                )
            )
            self._client_services[resolved] = _ClientService(command.message_name, handle, session, command.topic)
            self._clients[session].unity_services.add(resolved)
        self._ros.wait_registered("service", resolved)

    def unregister_client_service(
        self, session: ClientSession, registrations: ClientRegistrations, resolved: str
    ) -> None:
        with self._lock:
            registrations.unity_services.discard(resolved)
            service = self._client_services.get(resolved)
            if service is None or service.owner is not session:
                return
            del self._client_services[resolved]
            service.handle.shutdown("client removed the service")

    def call_client_service(self, resolved: str, request: bytes) -> bytes:
        """rospy service thread: forward a ROS request to the owning client and wait for its __response."""
        with self._lock:
            service = self._client_services.get(resolved)
            if service is None:
                raise RosError(f"service {resolved} has no client any more")
            if service.owner.queue.kept_bytes > self._config.client_queue_bytes:
                raise RosError(f"the client providing {resolved} does not read what it is sent")
            srv_id = next(self._srv_ids)
            call = _PendingCall(service.owner, service.service_type)
            self._pending[srv_id] = call
            client_name = service.client_name
        call.owner.send(protocol.encode(ServiceRequest(srv_id, client_name, request)), droppable=False)
        try:
            if not call.done.wait(self._config.service_timeout_s):
                raise RosError(f"client did not answer {resolved} within {self._config.service_timeout_s:g} s")
            if call.failure is not None:
                raise RosError(call.failure)
            assert call.response is not None
            return call.response
        finally:
            with self._lock:
                self._pending.pop(srv_id, None)

    def complete_client_call(self, session: ClientSession, response: ServiceResponse) -> None:
        srv_id = response.srv_id
        with self._lock:
            call = self._pending.get(srv_id)
        if call is None or call.owner is not session:
            raise RequestRefused(
                f"__response: unknown srv_id {srv_id} (never requested from this client, or timed out); "
                "response discarded",
                srv_id,
            )
        problem = self._bridged.payload_problem(call.service_type, response.payload, "response")
        if problem is not None:
            # The ROS caller hears at once instead of getting bytes it cannot read (or waiting for a timeout).
            call.failure = f"client {session.name} answered with an invalid response: {problem}"
            call.done.set()
            raise RequestRefused(
                f"__response {srv_id}: service {response.service}: {problem}; the ROS call fails", srv_id
            )
        call.response = response.payload
        call.done.set()

    # --- a client leaves, the endpoint stops ------------------------------------------------------------------
    def release(self, session: ClientSession, registrations: ClientRegistrations) -> None:
        """A departing client's services end, and the ROS calls waiting for it fail at once."""
        with self._lock:
            for resolved in list(registrations.unity_services):
                self.unregister_client_service(session, registrations, resolved)
            for call in self._pending.values():
                if call.owner is session:
                    call.failure = f"client {session.name} disconnected before answering"
                    call.done.set()

    def fail_waiting_calls(self, why: str, timeout_s: float = 1.0) -> None:
        """Every ROS call waiting for a client fails with `why`; returns once they have left for rospy to send their
        callers the error (before rospy's shutdown closes the connections, else a caller hears only that the
        connection broke), or after `timeout_s`."""
        with self._lock:
            for call in self._pending.values():
                call.failure = why
                call.done.set()
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            with self._lock:
                if not self._pending:
                    return
            time.sleep(0.01)
