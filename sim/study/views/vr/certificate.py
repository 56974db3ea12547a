"""The VR page's TLS certificate: self-signed, made once with `openssl` and kept, so that the headset's browser is
told to trust it once (a new certificate would ask again), and the machine's addresses it is reached by.

The certificate names localhost, 127.0.0.1 and the machine's addresses when it was made. The headset's browser warns
about any self-signed certificate whatever it names; the participant's experimenter accepts it once per headset.
"""

from __future__ import annotations

import ipaddress
import os
import socket
import subprocess
from pathlib import Path

from sim.study.views.errors import ViewError

__all__ = ["DEFAULT_CERTIFICATE_DIR", "machine_addresses", "machine_names", "ensure_certificate"]

DEFAULT_CERTIFICATE_DIR = Path.home() / ".ros" / "sim_study_vr"
VALID_DAYS = 825  # what browsers accept at most for a server certificate


def machine_addresses() -> list[str]:
    """This machine's IPv4 addresses a headset on the LAN could use, best first (none when it has no network)."""
    found: list[str] = []
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:  # a UDP "connect" sends nothing; it picks the address the default route leaves by
            probe.connect(("10.255.255.255", 1))
            found.append(probe.getsockname()[0])
        except OSError:
            pass
    try:
        infos = socket.getaddrinfo(socket.gethostname(), None, socket.AF_INET)
    except OSError:
        infos = []
    for info in infos:
        address = str(info[4][0])
        if address not in found:
            found.append(address)
    return [address for address in found if not ipaddress.ip_address(address).is_loopback]


def machine_names() -> list[str]:
    """This machine's own names: its host name and its fully qualified one (the page's server answers to them)."""
    return sorted({socket.gethostname(), socket.getfqdn()} - {""})


def ensure_certificate(folder: Path, addresses: list[str]) -> tuple[Path, Path]:
    """(certificate, key) in `folder`: those already there, or a new self-signed pair naming localhost, 127.0.0.1
    and `addresses`. ViewError when openssl is missing or fails."""
    certificate, key = folder / "certificate.pem", folder / "key.pem"
    if certificate.is_file() and key.is_file():
        return certificate, key
    folder.mkdir(parents=True, exist_ok=True)
    names = ["DNS:localhost", "IP:127.0.0.1"] + [f"IP:{address}" for address in addresses]
    command = [
        "openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-sha256", "-days", str(VALID_DAYS),
        "-subj", f"/CN={socket.gethostname()} (sim.study vr)", "-addext", f"subjectAltName={','.join(names)}",
        "-keyout", str(key), "-out", str(certificate),
    ]  # fmt: skip
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=60)
    except FileNotFoundError:
        raise ViewError("making the page's certificate needs openssl (sudo apt install openssl)") from None
    if done.returncode != 0:
        for path in (certificate, key):
            path.unlink(missing_ok=True)
        raise ViewError(f"openssl could not make the page's certificate: {done.stderr.strip()[-300:]}")
    os.chmod(key, 0o600)
    return certificate, key
