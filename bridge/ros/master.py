"""The endpoint node's link to the ROS master: registrations that never block, survive outages and follow restarts.

rospy tells its registration listeners of every publisher, subscriber and service the process creates or drops;
its own listener (RegManager) calls the master right there, under rospy's topic manager lock, retrying forever
while the master does not answer. `MasterLink` takes that listener's place: it only notes the change in a
RegistrationBook (bridge.ros.registry) and wakes its thread, which makes the calls with a timeout, watches the master's
identity (its pid and /run_id) once a second, and registers everything again when another master answers. rospy's
RegManager keeps its other job, connecting subscribers to the publishers the master names.

Every master call of the endpoint goes through `call_master`, with a timeout: a frozen master costs the caller
at most that, never a thread forever.
"""

from __future__ import annotations

import logging
import threading
import time
import xmlrpc.client
from typing import Any, Callable, Hashable

import rosgraph
import rospy
import rospy.impl.paramserver as rospy_paramserver
import rospy.impl.registration as rospy_registration
import rospy.impl.statistics as rospy_statistics
from rospy.impl.registration import Registration as RospyRegistration

from bridge.errors import BridgeError
from bridge.ros.registry import Registration, RegistrationBook

__all__ = [
    "MASTER_TIMEOUT_S",
    "MASTER_POLL_S",
    "MasterError",
    "MasterRefused",
    "timed_proxy",
    "call_master",
    "MasterLink",
]

log = logging.getLogger(__name__)

MASTER_TIMEOUT_S = 2.0  # one XML-RPC call to the master, connection included
MASTER_POLL_S = 1.0  # how often the master's identity is checked

_KIND_OF = {RospyRegistration.PUB: "publisher", RospyRegistration.SUB: "subscriber", RospyRegistration.SRV: "service"}


class MasterError(BridgeError, OSError):
    """The master did not answer in time, could not be reached, or refused the call (the text says which)."""


class MasterRefused(MasterError):
    """The master answered, and said no (e.g. a name it does not take)."""


class _TimedTransport(xmlrpc.client.Transport):
    def __init__(self, timeout_s: float) -> None:
        super().__init__()
        self._timeout_s = timeout_s

    def make_connection(self, host: Any) -> Any:
        connection = super().make_connection(host)
        connection.timeout = self._timeout_s  # used when it connects, and for every read
        return connection


def timed_proxy(uri: str, timeout_s: float = MASTER_TIMEOUT_S) -> xmlrpc.client.ServerProxy:
    """An XML-RPC proxy of a ROS master or node whose every call gives up after `timeout_s`."""
    return xmlrpc.client.ServerProxy(uri, transport=_TimedTransport(timeout_s))


def call_master(method: str, *args: Any, timeout_s: float = MASTER_TIMEOUT_S) -> Any:
    """The value of one master API call (its code checked); MasterError when it fails or takes too long."""
    uri = rosgraph.get_master_uri()
    proxy = timed_proxy(uri, timeout_s)
    try:
        code, message, value = getattr(proxy, method)(*args)
    except (OSError, xmlrpc.client.Error) as error:
        raise MasterError(f"the ROS master at {uri} did not answer {method} ({error})") from None
    if code != 1:
        raise MasterRefused(f"the ROS master refused {method}: {message}")
    return value


def _read_rospys_parameters_once() -> None:
    """Parameters rospy reads from the master with no timeout, at moments a frozen master must not block: asked
    once here instead.

    - Whether /enable_statistics is set, each time a subscriber is made, under rospy's topic manager lock (every
      registration of the process would wait): asked here with a timeout, and rospy's check answers from that.
    - /rosout_disable_topics_generation, on every message logged to /rosout while it is not set (e.g. a failed
      service call, on a rospy thread, holding the log handler's lock): read here with a timeout and put in rospy's
      parameter cache, which it reads first.
    """
    try:
        enabled = bool(call_master("getParam", rospy.get_caller_id(), "/enable_statistics"))
    except MasterError:
        enabled = False  # not set (the usual case), or no answer: rospy's own check says False then too
    rospy_statistics.SubscriberStatisticsLogger.is_enabled = classmethod(lambda cls: enabled)
    try:
        disabled = bool(call_master("getParam", rospy.get_caller_id(), "/rosout_disable_topics_generation"))
    except MasterError:
        disabled = False  # rospy's default
    rospy_paramserver.get_param_server_cache().set("/rosout_disable_topics_generation", disabled)


class MasterLink(rospy_registration.RegistrationListener):
    """Keeps the node's registrations on whatever master answers at ROS_MASTER_URI (see the module)."""

    def __init__(self, poll_s: float = MASTER_POLL_S, timeout_s: float = MASTER_TIMEOUT_S) -> None:
        self._poll_s = poll_s
        self._timeout_s = timeout_s
        self._book = RegistrationBook()
        self._changed = threading.Condition()
        self._stopping = False
        self._thread: threading.Thread | None = None
        self._rospy_registrar: Any = None  # rospy's RegManager: still connects our subscribers to publishers
        self._proxy: xmlrpc.client.ServerProxy | None = None  # the identity checks' connection
        self.master_up = True
        self.restarts = 0  # other masters seen since start
        self._on_new_master: list[Callable[[], None]] = []

    def on_new_master(self, callback: Callable[[], None]) -> None:
        """Call `callback` (on the link's thread) once everything is registered with a master that replaced another
        (e.g. to set parameters again: a new master's parameter server is empty)."""
        self._on_new_master.append(callback)

    # --- taking rospy's place -------------------------------------------------------------------------------------
    def install(self, wait_s: float = 30.0) -> None:
        """Replace rospy's registration listener with this link, once rospy has registered the node (init_node
        starts that on a thread of its own), and start the link's thread."""
        listeners = rospy_registration.get_registration_listeners()
        deadline = time.monotonic() + wait_s
        while True:
            with listeners.lock:
                registrar = next(
                    (each for each in listeners.listeners if isinstance(each, rospy_registration.RegManager)), None
                )
            if registrar is not None:
                break
            if time.monotonic() > deadline:
                raise MasterError(f"rospy did not register the node with the ROS master within {wait_s:g} s")
            time.sleep(0.01)
        try:
            identity: Hashable | None = self._identity()  # the master rospy registered with
        except MasterError as error:
            self._master_lost(error)
            identity = None
        topics, services = rospy_registration.get_topic_manager(), rospy_registration.get_service_manager()
        # What rospy registered so far, with no registration in between (both managers notify under their locks).
        with topics.lock, services.lock, listeners.lock:
            registered = [Registration("publisher", name, kind) for name, kind in topics.get_publications()]
            registered += [Registration("subscriber", name, kind) for name, kind in topics.get_subscriptions()]
            registered += [Registration("service", name, uri) for name, uri in services.get_services()]
            self._book = RegistrationBook(tuple(registered), identity)
            listeners.listeners[listeners.listeners.index(registrar)] = self
        self._rospy_registrar = registrar
        # rospy's clean-up at shutdown unregisters over XML-RPC with no timeout (a frozen master would keep the
        # process from ever exiting): the link does it instead, as the last thing it does.
        hooks = rospy.core._preshutdown_hooks
        if registrar.cleanup in hooks:
            hooks[hooks.index(registrar.cleanup)] = self._clean_up
        rospy.core.add_shutdown_hook(self._wake_registrar)
        _read_rospys_parameters_once()
        self._thread = threading.Thread(target=self._run, name="ROS master link", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Take back from the master what was withdrawn and not yet taken back (rospy's own clean-up at shutdown
        knows only what still exists), then end the link's thread; a master that does not answer is not waited
        for longer than one call's timeout."""
        with self._changed:
            self._stopping = True
            self._changed.notify_all()
        if self._thread is not None:
            self._thread.join(timeout=self._timeout_s + 0.5)

    def _clean_up(self, reason: str) -> None:
        """rospy's pre-shutdown hook in place of RegManager.cleanup: the same work, each master call bounded."""
        with self._rospy_registrar.cond:
            self._rospy_registrar.cond.notify_all()  # its thread sees the shutdown
        rospy_registration.get_registration_listeners().clear()
        self.stop()
        with self._changed:
            registrations = self._book.to_unregister() + self._book.wanted()
        if self.master_up and registrations:
            caller, node_uri = rospy.get_caller_id(), rospy.core.get_node_uri()
            calls = xmlrpc.client.MultiCall(timed_proxy(rosgraph.get_master_uri(), self._timeout_s))
            for registration in registrations:
                method, args = _unregistration(registration, caller, node_uri)
                getattr(calls, method)(*args)
            try:
                calls()
            except (OSError, xmlrpc.client.Error) as error:
                log.warning("could not unregister from the ROS master at shutdown: %s", error)
        rospy_registration.get_topic_manager().close_all()
        rospy_registration.get_service_manager().unregister_all()

    def _wake_registrar(self, reason: str) -> None:
        """rospy's shutdown hook, run once its shutdown flag is up: rospy's registration thread, which shutdown joins,
        checks the flag every 0.5 s and was last woken before the flag (in _clean_up), so without this the endpoint
        took half a second to exit."""
        with self._rospy_registrar.cond:
            self._rospy_registrar.cond.notify_all()

    def wait_registered(self, kind: str, name: str, timeout_s: float) -> bool:
        """Wait (up to `timeout_s`, and not at all while the master is not answering) until the master holds the
        registration of `name` as a `kind` ("publisher", "subscriber", "service"); whether it does. What a client
        registers is thus on the graph when its next command runs, as it was when rospy registered synchronously."""
        deadline = time.monotonic() + timeout_s
        with self._changed:
            while not self._book.holds(kind, name):
                remaining = deadline - time.monotonic()
                if remaining <= 0 or not self.master_up or self._stopping:
                    return False
                self._changed.wait(remaining)
            return True

    # --- rospy's RegistrationListener: called under rospy's locks, so only noted here --------------------------
    def reg_added(self, resolved_name: str, data_type_or_uri: str, reg_type: str) -> None:
        with self._changed:
            self._book.add(Registration(_KIND_OF[reg_type], resolved_name, data_type_or_uri))
            self._changed.notify_all()

    def reg_removed(self, resolved_name: str, data_type_or_uri: str, reg_type: str) -> None:
        with self._changed:
            self._book.remove(Registration(_KIND_OF[reg_type], resolved_name, data_type_or_uri))
            self._changed.notify_all()

    # --- the link's thread ---------------------------------------------------------------------------------------
    def _run(self) -> None:
        next_check = 0.0
        while True:
            with self._changed:
                if not self._stopping and not self._owed():
                    self._changed.wait(max(0.0, next_check - time.monotonic()))
                stopping = self._stopping
            if stopping:
                if self.master_up:
                    try:
                        self._settle(register=False)
                    except MasterError:
                        pass
                return
            try:
                if time.monotonic() >= next_check:
                    next_check = time.monotonic() + self._poll_s
                    self._check_master()
                if self.master_up:
                    self._settle()
            except MasterError as error:
                self._master_lost(error)
                next_check = time.monotonic() + self._poll_s
            except Exception:  # the link must outlive any surprise: it is what keeps the node on the graph
                log.exception("ROS master link: unexpected failure")
                next_check = time.monotonic() + self._poll_s

    def _owed(self) -> bool:
        return self.master_up and bool(self._book.to_register() or self._book.to_unregister())

    def _identity(self) -> Hashable:
        """(pid, /run_id) of the master answering now, in one request on the link's own connection, kept open
        between checks (a new connection each second would cost the master a thread each time). A kept connection
        that fails (the master restarted) is replaced and asked again at once."""
        for fresh in (self._proxy is None, True):
            if fresh or self._proxy is None:
                self._proxy = timed_proxy(rosgraph.get_master_uri(), self._timeout_s)
            calls = xmlrpc.client.MultiCall(self._proxy)
            caller = rospy.get_caller_id()
            calls.getPid(caller)
            calls.getParam(caller, "/run_id")
            try:
                answers: Any = calls()
                break
            except (OSError, xmlrpc.client.Error) as error:
                self._proxy = None
                if fresh:
                    raise MasterError(
                        f"the ROS master at {rosgraph.get_master_uri()} did not answer ({error})"
                    ) from None
        (pid_code, _, pid), (run_id_code, _, run_id) = answers[0], answers[1]
        if pid_code != 1:
            raise MasterError(f"the ROS master did not give its pid (code {pid_code})")
        return (pid, run_id if run_id_code == 1 else None)  # a bare rosmaster has no /run_id: its pid tells

    def _check_master(self) -> None:
        identity = self._identity()
        with self._changed:
            another = self._book.master_is(identity)
            counts = self._book.counts()
        if not self.master_up:
            self.master_up = True
            if not another:
                log.warning("the ROS master at %s answers again", rosgraph.get_master_uri())
        if another:
            self.restarts += 1
            log.warning(
                "a new ROS master at %s: registering %d publishers, %d subscribers and %d services again",
                rosgraph.get_master_uri(),
                counts["publisher"],
                counts["subscriber"],
                counts["service"],
            )
            self._settle()
            for callback in self._on_new_master:
                callback()

    def _master_lost(self, error: MasterError) -> None:
        if self.master_up:
            log.warning(
                "%s; the endpoint keeps serving its clients, and registers with the master when it answers", error
            )
        with self._changed:
            self.master_up = False
            self._changed.notify_all()  # nobody waits for a registration while the master does not answer

    def _settle(self, register: bool = True) -> None:
        """Take back what was withdrawn, then register what is owed; MasterError if the master stops answering."""
        with self._changed:
            withdrawn, owed = self._book.to_unregister(), self._book.to_register() if register else []
        for registration in withdrawn:
            self._call("unregister", registration)
            with self._changed:
                self._book.unregistered(registration)
        for registration in owed:
            publishers = self._call("register", registration)
            with self._changed:
                self._book.registered(registration)
                self._changed.notify_all()  # wait_registered
            if registration.kind == "subscriber" and publishers is not None:
                self._rospy_registrar.publisher_update(registration.name, publishers)

    def _call(self, action: str, registration: Registration) -> Any:
        """One (un)registration; a refusal is logged and counts as done (asking again would be refused again)."""
        caller, node_uri = rospy.get_caller_id(), rospy.core.get_node_uri()
        if action == "register":
            method = f"register{registration.kind.capitalize()}"
            args: tuple[str, ...] = (caller, registration.name, registration.detail, node_uri)
        else:
            method, args = _unregistration(registration, caller, node_uri)
        try:
            return call_master(method, *args, timeout_s=self._timeout_s)
        except MasterRefused as refusal:
            log.error("%s %s: %s", method, registration.name, refusal)
            return None


def _unregistration(registration: Registration, caller: str, node_uri: str) -> tuple[str, tuple[str, ...]]:
    """The master API call that takes `registration` back: a service by its URI, a topic by the node's."""
    method = f"unregister{registration.kind.capitalize()}"
    if registration.kind == "service":
        return method, (caller, registration.name, registration.detail)
    return method, (caller, registration.name, node_uri)
