"""Debian's Chromium, headless with WebGL in software, driven by Debian's chromedriver (no download), and the VR
page's server with its emulated headset: for the web pages' tests (the live view, the VR page) and the VR page's
frame-time bench."""

from __future__ import annotations

import secrets
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from sim.launchers import ButtonServer, VrServer, start
from sim.processes import ManagedProcess, plain_env
from sim.study.views.vr.relay import AUTH_TOKEN_ENV, PROXY_SECRET_ENV

CHROMIUM, CHROMEDRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"


def launch_secrets(auth_token: str | None = None) -> dict[str, str]:
    """One launch's secrets shared by an endpoint and its page servers, as the environment gives them: a new proxy
    secret (the endpoint believes the page server's X-Forwarded-For only with it), and the endpoint's `auth_token`
    when it has one (the page servers authenticate the pages with it)."""
    made = {PROXY_SECRET_ENV: secrets.token_urlsafe(18)}
    return made if auth_token is None else {**made, AUTH_TOKEN_ENV: auth_token}


def start_vr_page(
    websocket_port: int,
    log_dir: Path,
    frame_time: bool = False,
    robot: Sequence[str] = (),
    env: Mapping[str, str] | None = None,
) -> tuple[ManagedProcess, str]:
    """`python -m sim.study vr` with the emulated headset and the tests' probe (window.vrPage), and with `frame_time`
    the frame-time instrument (window.vrFrameTime), on a free port of localhost, passing its WebSocket to the
    endpoint's `websocket_port`, its certificate made in log_dir/certificate; `robot`: its --robot options (default:
    the scene's); `env`: more environment (launch_secrets). Returned once it serves, with the page's URL (and its
    key)."""
    server = VrServer(
        websocket_port,
        certificate_dir=log_dir / "certificate",
        emulate_headset=True,
        frame_time=frame_time,
        robot=robot,
    )
    vr = start(server, {**plain_env(), **(env or {})}, log_dir, "vr")
    return vr, server.page_url(vr.output())


def start_button_page(
    websocket_port: int, log_dir: Path, env: Mapping[str, str] | None = None
) -> tuple[ManagedProcess, str]:
    """`python -m sim.study button` with the emulated gamepad and the tests' probe (window.buttonPage), as
    start_vr_page starts the VR page. Returned once it serves, with the page's URL (and its key)."""
    server = ButtonServer(websocket_port, certificate_dir=log_dir / "certificate", emulate_gamepad=True)
    button = start(server, {**plain_env(), **(env or {})}, log_dir, "button")
    return button, server.page_url(button.output())


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
