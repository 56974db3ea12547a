"""A slow network link between a client and a server on one machine, for tests and benchmarks: a user-space TCP
relay with a rate limit, a one-way delay each way and small buffers (this kernel has no netem).

    link = SlowLink(("127.0.0.1", endpoint_port), rate_bps=100e6, delay_s=0.008).start()
    client connects to ("127.0.0.1", link.port) instead of the endpoint

Each direction of each connection is one pipe: a reader takes bytes from the sending side only as fast as the link's
rate allows (a token bucket; what the rate does not allow yet stays in the relay's small receive buffer, then in the
sender's own send buffer, as behind a real bottleneck), stamps them, and a writer hands them to the receiving side
`delay_s` later. The link itself holds at most `buffer_bytes` not yet sent on (its queue: T_buf = buffer_bytes /
rate) plus what is in flight (rate x delay). Every thread ends when either side closes, or when the link is stopped.
"""

from __future__ import annotations

import socket
import threading
import time
from collections import deque

__all__ = ["SlowLink"]

CHUNK_BYTES = 16 * 1024  # what the link moves at a time: 1.3 ms at 100 Mbit/s


class TokenBucket:
    """Bytes may pass at `rate` bytes/s, in bursts of at most `burst` bytes (pure but for the clock it is given)."""

    def __init__(self, rate: float, burst: int, now: float) -> None:
        self.rate, self.burst = rate, burst
        self._tokens = float(burst)
        self._at = now

    def wait_for(self, size: int, now: float) -> float:
        """Seconds until `size` bytes may pass (0 when they may now)."""
        self._refill(now)
        return max(0.0, (size - self._tokens) / self.rate)

    def take(self, size: int, now: float) -> None:
        self._refill(now)
        self._tokens -= size

    def _refill(self, now: float) -> None:
        self._tokens = min(float(self.burst), self._tokens + (now - self._at) * self.rate)
        self._at = now


class _Pipe:
    """One direction of one relayed connection."""

    def __init__(
        self, source: socket.socket, target: socket.socket, rate_Bps: float, delay_s: float, stopped: threading.Event
    ) -> None:
        self.source, self.target = source, target
        self.delay_s = delay_s
        self.bucket = TokenBucket(rate_Bps, CHUNK_BYTES, time.monotonic())
        self.stopped = stopped
        self.in_flight: deque[tuple[float, bytes]] = deque()
        self.ready = threading.Condition()
        self.ended = False
        self.threads = [
            threading.Thread(target=self._read, daemon=True),
            threading.Thread(target=self._write, daemon=True),
        ]

    def start(self) -> None:
        for thread in self.threads:
            thread.start()

    def _read(self) -> None:
        try:
            while not self.stopped.is_set():
                pause = self.bucket.wait_for(CHUNK_BYTES, time.monotonic())
                if pause:
                    time.sleep(pause)
                data = self.source.recv(CHUNK_BYTES)
                if not data:
                    break
                now = time.monotonic()
                self.bucket.take(len(data), now)
                # the bytes leave the link's queue now and arrive after the delay
                with self.ready:
                    self.in_flight.append((now + self.delay_s, data))
                    self.ready.notify()
        except OSError:
            pass
        finally:
            with self.ready:
                self.ended = True
                self.ready.notify()

    def _write(self) -> None:
        try:
            while not self.stopped.is_set():
                with self.ready:
                    while not self.in_flight and not self.ended:
                        self.ready.wait(0.5)
                    if not self.in_flight:
                        break
                    due, data = self.in_flight.popleft()
                pause = due - time.monotonic()
                if pause > 0:
                    time.sleep(pause)
                self.target.sendall(data)
        except OSError:
            pass
        finally:
            for sock in (self.target, self.source):
                try:
                    sock.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass


class SlowLink:
    """Listens on a free loopback port; every connection made to it is relayed to `server` through the link."""

    def __init__(
        self,
        server: tuple[str, int],
        rate_bps: float = 100e6,
        delay_s: float = 0.008,
        buffer_bytes: int = 64 * 1024,
        max_seconds: float = 600.0,
    ) -> None:
        self.server = server
        self.rate_Bps = rate_bps / 8.0
        self.delay_s = delay_s
        self.buffer_bytes = buffer_bytes
        self.max_seconds = max_seconds
        self._stopped = threading.Event()
        self._listener = self._small_buffered_socket()  # accepted connections inherit its buffer size
        self._listener.bind(("127.0.0.1", 0))
        self._listener.listen(64)
        self.port: int = self._listener.getsockname()[1]
        self._sockets: list[socket.socket] = []
        self._accepting: threading.Thread | None = None
        self._deadline = threading.Timer(max_seconds, self.stop)

    @property
    def buffer_time_s(self) -> float:
        """T_buf: how long the link's queue holds a byte at most, when full."""
        return self.buffer_bytes / self.rate_Bps

    def transmission_time_s(self, size: int) -> float:
        return size / self.rate_Bps

    def start(self) -> SlowLink:
        self._accepting = threading.Thread(target=self._accept, daemon=True)
        self._accepting.start()
        # bounded in time whatever the caller does; a daemon, cancelled by stop(), so it never holds up an exit
        self._deadline.daemon = True
        self._deadline.start()
        return self

    def stop(self) -> None:
        self._stopped.set()
        self._deadline.cancel()
        for sock in [self._listener, *self._sockets]:
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            sock.close()

    def __enter__(self) -> SlowLink:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _small_buffered_socket(self) -> socket.socket:
        """A TCP socket whose receive buffer is the link's queue (set before connecting, so the window is sized by
        it; Linux doubles the value asked for, and offers about half as window)."""
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, self.buffer_bytes)
        return sock

    def _accept(self) -> None:
        while not self._stopped.is_set():
            try:
                client, _ = self._listener.accept()
            except OSError:
                return  # stopped
            server = self._small_buffered_socket()
            try:
                server.settimeout(10)
                server.connect(self.server)
            except OSError:
                client.close()
                server.close()
                continue
            for sock in (client, server):
                sock.settimeout(None)
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                self._sockets.append(sock)
            for source, target in ((client, server), (server, client)):
                _Pipe(source, target, self.rate_Bps, self.delay_s, self._stopped).start()
