"""The page servers' command line (sim.study.views.cli): what it refuses before it serves anything."""

from __future__ import annotations

import subprocess
import sys

import pytest

from sim.entry import EXIT_BAD_INPUT
from sim.study.views.vr.access import is_loopback


@pytest.mark.parametrize(
    ("host", "loopback"),
    [
        ("127.0.0.1", True),
        ("127.0.0.2", True),
        ("::1", True),
        ("localhost", True),
        ("LocalHost", True),
        ("0.0.0.0", False),
        ("::", False),
        ("192.168.1.10", False),
        ("labpc", False),
    ],
)
def test_only_localhost_and_loopback_addresses_are_loopback(host: str, loopback: bool) -> None:
    assert is_loopback(host) is loopback


@pytest.mark.parametrize(("page", "host"), [("button", "0.0.0.0"), ("vr", "192.168.1.10")])
def test_plain_http_on_a_lan_address_is_refused_in_one_line(page: str, host: str) -> None:
    """The key and its cookie would cross the LAN in clear: refused before the server listens (the old command
    served, and the run timed out)."""
    argv = [sys.executable, "-m", "sim.study", page, "--websocket-port", "9", "--port", "0", "--host", host]
    done = subprocess.run([*argv, "--plain-http"], capture_output=True, text=True, timeout=60)
    assert done.returncode == EXIT_BAD_INPUT, done.stdout + done.stderr
    # pybullet, which sim.study imports, prints its build time first: not the command's
    lines = [line for line in done.stderr.strip().splitlines() if not line.startswith("pybullet build time")]
    assert len(lines) == 1 and lines[0].startswith(f"sim.study {page}: error: "), lines
    assert f"--plain-http with --host {host}" in lines[0] and "in clear" in lines[0], lines
    assert done.stdout == ""
