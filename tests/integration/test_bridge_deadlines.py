"""Deadlines and the memory of unfinished frames: a frame begun must complete in time, __auth must come in time,
wrong tokens are slowed down, and frames not yet complete share one budget for all clients."""

from __future__ import annotations

import struct
import time
from pathlib import Path

import pytest

from bridge import protocol
from tests.integration.bridge_helpers import ConnectionClosed, RawConnection, start_endpoint, tcp_client

TOKEN = "deadline-secret"


def test_a_frame_dribbled_too_slowly_is_cut_off_and_others_do_not_notice(roscore, ros_node, tmp_path: Path) -> None:
    endpoint = start_endpoint(roscore, tmp_path, "--frame-timeout", "1.5")
    try:
        with RawConnection(endpoint.port) as good, RawConnection(endpoint.port) as slow:
            frame = protocol.encode_syscommand("__topic_list", {})
            started = time.monotonic()
            for byte in frame[:-1]:  # one byte every 0.2 s: never complete within 1.5 s
                try:
                    slow.send(bytes([byte]))
                except OSError:  # cut off
                    break
                time.sleep(0.2)
            slow.expect_error("--frame-timeout", timeout=5)
            slow.wait_closed(timeout=5)
            assert time.monotonic() - started < 5
            good.sync()
            # keepalives and complete frames, however far apart, are not a frame left begun
            good.send(protocol.KEEPALIVE_FRAME)
            time.sleep(2)
            good.sync()
    finally:
        endpoint.stop()


def test_a_client_that_never_sends_its_token_is_dropped(roscore, ros_node, tmp_path: Path) -> None:
    endpoint = start_endpoint(roscore, tmp_path, "--auth-token", TOKEN, "--auth-timeout", "1")
    try:
        with RawConnection(endpoint.port) as silent:
            silent.send(protocol.KEEPALIVE_FRAME)  # keepalives are no __auth
            silent.expect_error("--auth-timeout", timeout=5)
            silent.wait_closed(timeout=5)
        with tcp_client(endpoint.port, reconnect=False, auth_token=TOKEN) as client:  # a timely one stays
            client.topic_list()
            time.sleep(1.5)
            client.topic_list()
            assert client.connections == 1
    finally:
        endpoint.stop()


def test_wrong_tokens_are_slowed_down_and_logged_once_a_second(roscore, ros_node, tmp_path: Path) -> None:
    endpoint = start_endpoint(roscore, tmp_path, "--auth-token", TOKEN)
    try:
        verdicts = 0
        started = time.monotonic()
        while time.monotonic() - started < 3:  # one guess at a time, as fast as the verdicts come
            with RawConnection(endpoint.port) as guesser:
                guesser.command("__auth", token=f"guess{verdicts}")
                guesser.wait_closed(timeout=30)
                verdicts += 1
        # 0.1 + 0.2 + 0.4 + 0.8 + 1.6 s: at most 5 or 6 verdicts in 3 s, where thousands came before
        assert verdicts <= 6, verdicts
        with tcp_client(endpoint.port, reconnect=False, auth_token=TOKEN) as client:  # the right token: at once
            client.topic_list(timeout=1)
        warnings = [
            line
            for line in endpoint.output().splitlines()
            if "authentication failed" in line and "disconnected" not in line
        ]
        assert 1 <= len(warnings) <= 4  # once a second at most (each connection's end is logged as it ends)
    finally:
        endpoint.stop()


def test_frames_not_yet_complete_share_one_budget(roscore, ros_node, tmp_path: Path) -> None:
    endpoint = start_endpoint(roscore, tmp_path, "--max-partial-frame-bytes", str(8 << 20))
    try:
        big = 6 << 20

        def header(destination: bytes) -> bytes:
            return struct.pack("<I", len(destination)) + destination + struct.pack("<I", big)

        with RawConnection(endpoint.port) as first, RawConnection(endpoint.port) as second, RawConnection(
            endpoint.port
        ) as good:
            # 5 MiB of a 6 MiB frame each would make 10 MiB. Each connection has its own reader thread, and sendall
            # returns once the kernel holds the bytes, so which of the two the endpoint reads first is not ours to
            # choose: whichever comes second is refused, the other keeps its frame.
            begun = {first: b"/bt_budget_a", second: b"/bt_budget_b"}
            for connection, destination in begun.items():
                try:
                    connection.send(header(destination) + b"\0" * (5 << 20))
                except OSError:  # refused (and reset) while sending
                    pass
            refused = first_closed([first, second], timeout=20)
            assert any("--max-partial-frame-bytes" in text for text in refused.errors()), refused.summary()
            kept = second if refused is first else first
            kept.send(b"\0" * (1 << 20))  # it completes its frame: a message for an unregistered topic
            kept.expect_error(begun[kept].decode(), "__publish")
            kept.sync()
            good.sync()
        with RawConnection(endpoint.port) as later:  # the budget is free again
            later.send(header(b"/bt_budget_c") + b"\0" * big)
            later.expect_error("/bt_budget_c", "__publish")
    finally:
        endpoint.stop()


def first_closed(connections: list[RawConnection], timeout: float) -> RawConnection:
    """The first of `connections` the endpoint closes, reading (and keeping) their frames meanwhile."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for connection in connections:
            try:
                connection.next_frame(0.05)
            except TimeoutError:
                continue
            except ConnectionClosed:
                return connection
    raise TimeoutError(f"none of the connections was closed within {timeout} s")


pytestmark = [pytest.mark.lane("endpoint", on=("noetic",)), pytest.mark.timeout(120)]
