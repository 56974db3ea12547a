"""The endpoint's ROS publisher of one topic, fed by the clients' reader threads: direct when ROS keeps up, a bounded
queue and a pump thread otherwise, flow control back to the client, and no ROS subscriber that stops reading able
to hold up the others.
"""

from __future__ import annotations

import logging
import struct
import threading
from typing import Any

import rospy
import rospy.impl.tcpros_pubsub

from bridge.connection.queues import OutgoingQueue
from bridge.connection.sockets import send_to_all, takes_whole, unsent_bytes
from bridge.protocol.framing import LARGE_PAYLOAD_BYTES
from bridge.ros.raw_types import RawMessage

log = logging.getLogger(__name__)
_U32 = struct.Struct("<I")

__all__ = ["PUBLISH_WAIT_S", "SUBSCRIBER_STALL_S", "DIRECT_PUBLISH_MAX_BYTES", "RawPublisher", "end_topic"]

# How long a client's reader waits for room in a full publisher queue before the ROS side counts as stalled.
PUBLISH_WAIT_S = 0.05
# A ROS subscriber connection that takes no bytes for this long while a batch waits for it has stopped reading (a
# frozen or wedged node): it is closed, so the topic's other subscribers, which already have the batch, get the next
# one too. A subscriber that reads slowly but steadily is waited for instead (flow control, see RawPublisher).
SUBSCRIBER_STALL_S = 1.0
# Messages up to this size take RawPublisher's direct path without asking for the send buffer's size: far below the
# smallest send buffer (16 KiB), so an empty, acknowledged send queue always takes them whole.
DIRECT_PUBLISH_MAX_BYTES = 8 * 1024


def end_topic(topic: Any) -> None:
    """Unregister a rospy publisher or subscriber and, once rospy has closed the topic, free its poller's
    descriptor: rospy leaves it to the garbage collector, which may not run for a long time (an endpoint whose
    clients come and go would run out of descriptors)."""
    impl = topic.impl
    topic.unregister()
    poller: Any = getattr(getattr(impl, "connection_poll", None), "poller", None)
    if impl is not None and impl.closed and hasattr(poller, "close"):
        poller.close()


class RawPublisher:
    """A ROS publisher fed by clients' reader threads, which must never block on ROS subscribers for long.

    Two ways to ROS, one writer at a time (`_write_lock`), so messages keep their order:
    - direct: a message that arrived alone (not in a burst), with nothing queued and every subscriber connection's
      sent bytes acknowledged, is written at once on the reader's thread, when each connection's send buffer takes
      it whole (bridge.connection.sockets.takes_whole: any small message; a camera image once the kernel has grown
      the buffer for it). That saves the pump's wake-up, one thread hop of every 1 kHz round trip and ~0.15 ms of a
      1 MiB one, and never blocks.
    - queued: everything else goes to a bounded drop-oldest queue of the client's `queue_size` (as rospy's queued
      publisher keeps per subscriber). One pump thread per topic drains it a batch at a time into rospy's
      *synchronous* publisher: one hand-off per batch instead of rospy's wake-up, sleep(0) and socket write per
      message. A batch goes to each subscriber connection as one write of back-to-back TCPROS frames
      (u32 length + bytes), see `_write_batch`.

    Flow control: when the queue is full, `publish` waits up to PUBLISH_WAIT_S for the pump to make room, so the
    client's reader (and, through TCP, the client) is slowed to the pace of the ROS subscribers instead of having
    its messages dropped, as a rospy node with a synchronous publisher would be. Measured: without it, a client
    flooding at 230k msg/s made the endpoint spend its GIL on frames it then dropped, and only 86k msg/s reached
    ROS. A ROS side that makes no room within that time is stalled: the queue then drops oldest at once (the
    client is told by __warn) until the pump completes a write again, so a stuck ROS subscriber costs the client
    one wait, never its other traffic. A ROS subscriber that stops reading altogether is cut off after
    SUBSCRIBER_STALL_S (rospy's synchronous publisher would wait for it forever, and the topic's other
    subscribers with it); the others get every batch at once meanwhile.
    """

    def __init__(
        self, publisher: Any, raw_class: type[RawMessage], message_name: str, queue_size: int, max_queue_bytes: int
    ) -> None:
        self._publisher = publisher
        self._raw_class = raw_class
        self._latch = bool(publisher.impl.is_latch)
        self.message_name = message_name
        self.queue = OutgoingQueue(max(queue_size, 1), max_queue_bytes)
        self._write_lock = threading.Lock()  # held while writing to the subscriber connections
        self._stalled = False  # set by publish when no room came in time; cleared by the pump's next write
        self.published = 0  # client messages handed over (for /diagnostics); clients' readers count at once
        self._published_lock = threading.Lock()
        self._pump = threading.Thread(target=self._pump_loop, name=f"pump {publisher.resolved_name}", daemon=True)
        self._pump.start()

    def publish(self, payloads: list[bytes], alone: bool = False) -> int:
        """Send messages to ROS, in order: those of one client read (one lock hand-off for all of them). A message
        that came `alone` goes directly if ROS keeps up; the rest through the queue, waiting for room unless the
        ROS side is stalled (see the class). Returns how many older queued messages were dropped to make room."""
        with self._published_lock:
            self.published += len(payloads)
        if alone and len(payloads) == 1 and not self._latch and self._write_lock.acquire(blocking=False):
            try:
                if not self.queue and self._subscribers_take_whole(len(payloads[0])):
                    self._write_batch(payloads)
                    return 0
            finally:
                self._write_lock.release()
        dropped = self.queue.put_many(payloads, wait_s=0.0 if self._stalled else PUBLISH_WAIT_S)
        if dropped:
            self._stalled = True
        return dropped

    def _subscribers_take_whole(self, size: int) -> bool:
        """Every subscriber connection takes a message of `size` bytes whole at once (see the class)."""
        impl = self._publisher.impl
        if impl is None:
            return False
        small = size + 4 <= DIRECT_PUBLISH_MAX_BYTES
        for connection in impl.connections:
            sock = getattr(connection, "socket", None)
            if sock is None or unsent_bytes(sock) or not (small or takes_whole(sock, size + 4)):
                return False
        return True

    def connections(self) -> int:
        """ROS subscribers connected."""
        return int(self._publisher.get_num_connections())

    def unregister(self) -> None:
        """The pump writes what is queued, then takes the topic off the graph (never waited for here: the caller
        holds the endpoint's lock, and a write to a stalled subscriber may take long)."""
        self.queue.close()

    def _pump_loop(self) -> None:
        while True:
            if not self.queue.wait():  # closed, and everything queued is written
                end_topic(self._publisher)
                return
            with self._write_lock:
                self._write_queued()

    def _write_queued(self) -> None:
        batch = self.queue.take_all(timeout=0)
        if batch:
            try:
                if self._latch:
                    # Latched topics take rospy's own path, which also records the latch for late subscribers.
                    for payload in batch:
                        self._publisher.publish(self._raw_class(payload))
                else:
                    self._write_batch(batch)
                self._stalled = False
            except Exception:  # rospy shutting down, topic closed: a lost batch, never a dead pump
                if not rospy.is_shutdown():
                    log.exception("publishing on %s failed", self._publisher.resolved_name)

    def _write_batch(self, payloads: list[bytes]) -> None:
        """What rospy's _PublisherImpl.publish does for one message (same lock, same stats; a connection whose write
        fails is closed, and rospy then removes it), done once for the whole batch, and without letting one ROS
        subscriber that stopped reading hold up the others: see bridge.connection.sockets.send_to_all and
        SUBSCRIBER_STALL_S."""
        impl = self._publisher.impl
        if impl is None or impl.closed:
            return
        pieces = _tcpros_pieces(payloads)
        size = sum(len(piece) for piece in pieces)
        failed: dict[Any, str] = {}
        impl.acquire()
        try:
            if impl.closed or not impl.has_connections() or rospy.is_shutdown():
                return
            # rospy replaces impl.connections on change, never mutates it
            connections = [c for c in impl.connections if not c.done and c.socket is not None]
            for piece in pieces:
                writing = [c for c in connections if c not in failed]
                for index, why in send_to_all([c.socket for c in writing], piece, SUBSCRIBER_STALL_S).items():
                    failed[writing[index]] = why
            for connection in connections:
                if connection not in failed:
                    connection.stat_bytes += size
                    connection.stat_num_msg += len(payloads)
            impl.seq += len(payloads)
            impl.message_data_sent += size
        finally:
            impl.release()
        for connection, why in failed.items():
            log.warning(
                "ROS subscriber %s of %s: %s; connection closed (a rospy subscriber connects again)",
                connection.endpoint_id,
                impl.resolved_name,
                why,
            )
            try:
                connection.close()  # calls back into impl.remove_connection
            except Exception:
                pass


def _tcpros_pieces(payloads: list[bytes]) -> list[bytes]:
    """The TCPROS frames (u32 length + bytes) of `payloads`, back to back, as few pieces to write: small messages
    joined with their length prefixes, a large one (LARGE_PAYLOAD_BYTES or more) written as it is, after its prefix,
    so its bytes are not copied once more."""
    pieces: list[bytes] = []
    joined: list[bytes] = []
    for payload in payloads:
        joined.append(_U32.pack(len(payload)))
        if len(payload) < LARGE_PAYLOAD_BYTES:
            joined.append(payload)
        else:
            pieces += (b"".join(joined), payload)
            joined = []
    if joined:
        pieces.append(b"".join(joined))
    return pieces
