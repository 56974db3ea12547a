"""Debian's Chromium, headless with WebGL in software, driven by Debian's chromedriver (no download), and the VR
page's server with its emulated headset: for the web pages' tests (the live view, the VR page) and the VR page's
frame-time bench."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from sim.processes import PYTHON, ManagedProcess, plain_env

CHROMIUM, CHROMEDRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"


def start_vr_page(websocket_port: int, log_dir: Path) -> tuple[ManagedProcess, str]:
    """`python -m sim.study vr` with the emulated headset on a free port of localhost, passing its WebSocket to the
    endpoint's `websocket_port`, its certificate made in log_dir/certificate; returned once it serves, with the
    page's URL."""
    vr = ManagedProcess(
        [
            *(PYTHON, "-m", "sim.study", "vr", "--websocket-port", str(websocket_port)),
            *("--port", "0", "--host", "127.0.0.1", "--certificate-dir", str(log_dir / "certificate")),
            "--emulate-headset",
        ],
        plain_env(),
        log_dir,
        "vr",
    )
    try:
        lines = vr.wait_for_output("its WebSocket /ros goes to", timeout=60).splitlines()
    except BaseException:
        vr.stop()
        raise
    return vr, next(line.split("the page: ")[1] for line in lines if "the page: " in line)


@contextmanager
def chromium(profile: Path, accept_insecure_certs: bool = False, size: str = "1200,900") -> Iterator[Any]:
    """A headless Chromium with its own profile folder; `accept_insecure_certs` for a self-signed certificate."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for argument in (
        "--headless=new",
        "--no-sandbox",
        "--disable-dev-shm-usage",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        f"--window-size={size}",
        f"--user-data-dir={profile}",
    ):
        options.add_argument(argument)
    if accept_insecure_certs:
        options.set_capability("acceptInsecureCerts", True)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    try:
        yield driver
    finally:
        driver.quit()
