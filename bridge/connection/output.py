"""The way out to one client of the endpoint: frames go out directly when its socket keeps up, otherwise through a
bounded queue drained by a writer thread, so a slow reader loses its oldest topic frames, never the endpoint's
memory; and the warnings that tell the client what was lost.

SessionOutput is the half of a ClientSession (bridge.connection.session) that writes; the session, which reads,
closes and owns the connection's life, is made of it.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from typing import TYPE_CHECKING

from bridge import protocol
from bridge.admission.throttle import LogThrottle
from bridge.config import EndpointConfig
from bridge.connection.queues import OutgoingQueue
from bridge.connection.sockets import UnsentLimit, send_now, takes_whole, unsent_bytes, wait_writable
from bridge.protocol.framing import LARGE_PAYLOAD_BYTES

if TYPE_CHECKING:  # wsproto is optional: bridge.protocol.websocket is imported only for WebSocket clients
    from bridge.protocol.websocket import WebSocketLink

__all__ = ["SessionOutput", "DIRECT_SEND_MAX_UNSENT", "DROP_WARNING_INTERVAL_S"]

log = logging.getLogger(__name__)

# A client with more than this waiting unacknowledged in its socket is not keeping up: no direct sends to it.
DIRECT_SEND_MAX_UNSENT = 64 * 1024
DROP_WARNING_INTERVAL_S = 1.0
ERROR_LOG_INTERVAL_S = 1.0


class SessionOutput:
    """The outgoing side of one client's connection: direct sends, the queue and its writer thread, drop warnings.

    What it needs of the session it is part of is declared below: the connection's name, whether it is closing,
    its WebSocket link (None over TCP), how it closes, and the counts of what was lost on the way in."""

    name: str
    _closed: threading.Event
    _link: WebSocketLink | None
    publish_drops: int
    pongs_refused: int
    _answers_budget: int

    def __init__(self, config: EndpointConfig, sock: socket.socket) -> None:
        self.sock = sock
        # Small frames go before queued large ones (take_batch): control messages never wait behind camera images.
        self.queue = OutgoingQueue(config.client_queue_frames, config.client_queue_bytes, LARGE_PAYLOAD_BYTES)
        self.frames_out = 0
        self.bytes_out = 0
        self._send_lock = threading.Lock()  # one writer of the socket at a time: direct sends or the writer thread
        self._unsent_bound = 0  # at least the bytes waiting in the kernel's send queue (see _peer_keeps_up)
        self._unsent_limit = UnsentLimit(sock)  # we decide what goes next, not the kernel, once the client is behind
        self._reported_drops = 0
        self._reported_publish_drops = 0
        self._reported_pongs_refused = 0
        self._last_drop_warning_at = 0.0
        self._error_log = LogThrottle(log, ERROR_LOG_INTERVAL_S)
        self._writer = threading.Thread(target=self._write_loop, name=f"write {self.name}", daemon=True)

    def close(self, reason: str | None = None, tell_client: bool = False) -> None:
        raise NotImplementedError  # the session's

    def _ended(self, reason: str) -> None:
        raise NotImplementedError  # the session's

    @property
    def dropped(self) -> int:
        """Frames for this client dropped because it read too slowly."""
        return self.queue.dropped

    def send(self, frame: bytes, droppable: bool = True, key: str | None = None, key_limit: int = 0) -> None:
        """Send one frame (or a service header + body, as one item) without ever blocking the caller.

        Direct path: when nothing is queued, nobody is writing and the peer keeps up, write it at once with a
        non-blocking send on the calling thread (a rospy callback, a reader), which saves the writer thread's
        wake-up and keeps 1 kHz latency low. Whatever the socket does not take goes to the queue: the unsent rest of
        a frame as non-droppable (it must follow its first bytes), so frames stay whole and in order. The writer
        thread takes the same lock for each batch, so the two paths never interleave bytes. A peer that does not
        keep up (DIRECT_SEND_MAX_UNSENT bytes waiting in the kernel) is left to the writer thread: measured, sending
        to a never-reading client from rospy's receive thread slowed that thread to ~580 msg/s for every client.
        The kernel is asked (an ioctl, a fifth of a fan-out's cost) only when what was written since it last
        answered could have reached the limit. `key` and `key_limit`: at most that many frames of the key (a topic)
        wait in the queue, the oldest going first (the client's queue_size for the topic).
        """
        if self._send_lock.acquire(blocking=False):
            try:
                if not self.queue and not self._closed.is_set() and self._peer_keeps_up(len(frame)):
                    try:
                        sent = send_now(self.sock, frame)
                    except OSError as error:  # the connection is gone; the reader sees it too and cleans up
                        self.close(f"send failed: {error}")
                        return
                    self._unsent_bound += sent
                    self.bytes_out += sent
                    if sent == len(frame):
                        self.frames_out += 1
                        return
                    if sent:
                        self.queue.put_continuation(frame[sent:])
                        return
            finally:
                self._send_lock.release()
        self.queue.put(frame, droppable, key=key, key_limit=key_limit)

    # Bytes ready for the socket as they are, whatever the transport (a WebSocket link's own replies): this class's
    # send, which WebSocketSession's send wraps.
    _send_bytes = send

    def _peer_keeps_up(self, size: int) -> bool:
        """Fewer than DIRECT_SEND_MAX_UNSENT bytes would wait in the kernel after sending `size` more; or, for a
        large frame (a camera image), the client has taken everything and the send buffer takes the frame whole
        (sockets.takes_whole), which saves a local client the writer thread's wake-up (~0.15 ms of a 1 MiB round
        trip); on a slow link, the next image then finds the first still going and waits in the queue. Called with
        the send lock held; `_unsent_bound` is the last measured backlog plus everything written since."""
        if self._unsent_bound + size < DIRECT_SEND_MAX_UNSENT:
            return True
        self._unsent_bound = unsent_bytes(self.sock)
        if self._unsent_bound + size < DIRECT_SEND_MAX_UNSENT:
            return True
        return size >= LARGE_PAYLOAD_BYTES and not self._unsent_bound and takes_whole(self.sock, size)

    def send_error(self, text: str, srv_id: int | None = None) -> None:
        # Errors are diagnostics (Unity only logs them): droppable, so a client that floods bad input and never
        # reads cannot grow the endpoint's memory; and logged at most once a second per client, so it cannot
        # flood the log either.
        self._error_log.warning("client %s: %s", self.name, text)
        self.send(protocol.encode(protocol.Error(text, srv_id)), droppable=True)

    # --- writer -----------------------------------------------------------------------------------------------
    def _write_loop(self) -> None:
        try:
            while self.queue.wait(timeout=DROP_WARNING_INTERVAL_S):
                if self.queue.large_queued:
                    # A client behind on large frames gets the kernel's limit, and its next batch is chosen when the
                    # link can take it: what came meanwhile (a joint state, a newer image) may then go first.
                    self._unsent_limit.before_large_write()
                    if self._unsent_limit.limited and not wait_writable(self.sock, DROP_WARNING_INTERVAL_S):
                        continue
                # Take the batch under the send lock: a direct send (see send) can then never slip between
                # taking frames off the queue and writing them.
                with self._send_lock:
                    batch = self.queue.take_batch()
                    # Nothing after a WebSocket's Close: a batch that holds it was taken after _closed was set
                    warning = None if self._closed.is_set() else self._drop_warning()
                    if warning is not None:
                        batch.append(warning)
                    if batch:
                        data = b"".join(batch)
                        self.sock.sendall(data)
                        self.bytes_out += len(data)
                        self.frames_out += len(batch)
                        self._unsent_bound += len(data)
        except OSError as error:
            self._ended(f"write failed: {error}")
            self.close()

    def _drop_warning(self) -> bytes | None:
        """At most once per wake-up (>= 1 s apart when idle): how many frames were lost each way, and how many
        WebSocket pongs were not sent."""
        dropped, publish_dropped, pongs_refused = self.queue.dropped, self.publish_drops, self.pongs_refused
        if (
            dropped == self._reported_drops
            and publish_dropped == self._reported_publish_drops
            and pongs_refused == self._reported_pongs_refused
        ):
            return None
        now = time.monotonic()
        if now - self._last_drop_warning_at < DROP_WARNING_INTERVAL_S:
            return None
        self._last_drop_warning_at = now
        parts = []
        if dropped != self._reported_drops:
            parts.append(
                f"client reads too slowly: {dropped - self._reported_drops} outgoing message(s) dropped "
                f"(oldest first), {dropped} in total"
            )
        if publish_dropped != self._reported_publish_drops:
            parts.append(
                f"ROS subscribers take this client's messages too slowly: "
                f"{publish_dropped - self._reported_publish_drops} published message(s) dropped (oldest first; "
                f"raise queue_size in __publish), {publish_dropped} in total"
            )
        if pongs_refused != self._reported_pongs_refused:
            parts.append(
                f"{pongs_refused - self._reported_pongs_refused} WebSocket pong(s) not sent: more than "
                f"{self._answers_budget} bytes of earlier answers waited unread, {pongs_refused} in total"
            )
        self._reported_drops, self._reported_publish_drops = dropped, publish_dropped
        self._reported_pongs_refused = pongs_refused
        warning = protocol.encode(protocol.Warn("; ".join(parts)))
        return warning if self._link is None else self._link.wrap(warning)
