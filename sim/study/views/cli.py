"""`python -m sim.study view` (the experimenter's live 3-D view, a viser page), `vr` (the VR condition's page for
a WebXR headset, over HTTPS) and `button` (the reality condition's stop button page: a USB button, foot pedal or
gamepad read by the browser's Gamepad API, served by the VR page's server)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from sim.entry import EXIT_NO_CONNECTION, EXIT_OK, fail
from sim.study.checks import check_port, check_positive
from sim.study.design.options import add_robot_options, add_scene_options, scene_and_robot
from sim.study.views.errors import ViewError

if TYPE_CHECKING:
    from sim.study.views.vr.site import Site

__all__ = ["register"]


def register(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    view = commands.add_parser("view", help="the experimenter's live 3-D view, a web page (viser)")
    view.add_argument("--host", default="127.0.0.1", help="endpoint address")
    view.add_argument("--port", type=int, default=10000, help="endpoint port")
    view.add_argument("--http-host", default="127.0.0.1", help="the page's address (0.0.0.0: every interface)")
    view.add_argument("--http-port", type=int, default=8080, help="the page's port (default 8080)")
    view.add_argument("--rate", type=float, default=20.0, help="page updates per second at most (default 20)")
    add_scene_options(view)
    view.set_defaults(handler=view_command)

    vr = commands.add_parser("vr", help="the VR condition's page for a WebXR headset (docs/study.md)")
    _add_server_options(vr, 8443)
    vr.add_argument(
        "--emulate-headset",
        action="store_true",
        help="load an emulated Quest 3 (IWER) in the page, and the tests' probe (window.vrPage): for tests and for "
        "trying the page without a headset",
    )
    vr.add_argument(
        "--frame-time",
        action="store_true",
        help="load the frame-time instrument (window.vrFrameTime) in the page: for bench/vr_frame_bench.py",
    )
    vr.add_argument(
        "--pose-conditions",
        default="vr",
        metavar="CONDITIONS",
        help="the conditions whose trials the page sends the headset's and controllers' poses in, comma-separated "
        "(default vr; vr,reality: the headset worn in reality too, with passthrough; none: another tracker tracks "
        "both)",
    )
    vr.add_argument(
        "--rest",
        type=float,
        default=None,
        metavar="S",
        help="seconds the participant holds head and hands still at the session's start, for the tracking's jitter "
        "(default 3, as the tracker relay's rest)",
    )
    add_robot_options(vr)
    vr.set_defaults(handler=vr_command)

    button = commands.add_parser(
        "button", help="the reality condition's stop button page: a USB button, pedal or gamepad (docs/study.md)"
    )
    _add_server_options(button, 8444)
    button.add_argument(
        "--emulate-gamepad",
        action="store_true",
        help="load an emulated gamepad in the page (window.emulatedGamepad) and the tests' probe (window.buttonPage): "
        "for tests and for trying the page without a pedal",
    )
    button.set_defaults(handler=button_command)


def _add_server_options(parser: argparse.ArgumentParser, port: int) -> None:
    """The page server's options, the same for every page it serves."""
    parser.epilog = (
        "It prints the page's address with a key made at each launch: only browsers that opened it reach the "
        "endpoint. From the environment: ROS_TCP_AUTH_TOKEN, the endpoint's --auth-token (the server authenticates "
        "the pages; the browser never holds it); ROS_TCP_PROXY_SECRET, the endpoint's proxy secret, shown with each "
        "browser's address."
    )
    parser.add_argument("--endpoint-host", default="127.0.0.1", help="the endpoint's address")
    parser.add_argument(
        "--websocket-port", type=int, default=9090, help="the endpoint's --websocket-port (default 9090)"
    )
    parser.add_argument(
        "--host",
        default="127.0.0.1",
        help="the address to listen on (default 127.0.0.1: this machine only, which `adb reverse` reaches); a "
        "headset on the LAN needs the machine's LAN address, or 0.0.0.0 for every interface",
    )
    parser.add_argument("--port", type=int, default=port, help=f"the page's port (default {port}; 0 picks a free one)")
    parser.add_argument(
        "--allow-host",
        action="append",
        default=[],
        metavar="NAME",
        help="a name the page is opened by, beyond this machine's own names and addresses (repeatable): requests "
        "naming any other host are refused",
    )
    parser.add_argument(
        "--plain-http",
        action="store_true",
        help="HTTP without TLS: only for a browser on this machine or behind `adb reverse` (localhost is secure); "
        "refused with a --host other than localhost or a loopback address",
    )
    parser.add_argument("--certificate", type=Path, help="your own TLS certificate (PEM), with --key")
    parser.add_argument("--key", type=Path, help="the key of --certificate (PEM)")
    parser.add_argument(
        "--certificate-dir",
        type=Path,
        help="where the self-signed certificate is made once and kept (default ~/.ros/sim_study_vr)",
    )


def view_command(args: argparse.Namespace) -> int:
    import signal
    import threading

    import viser

    from bridge.client import ClientError, TcpClient
    from sim.study.views.live import LiveView

    check_positive(args.rate, "--rate")
    check_positive(args.dt, "--dt")
    check_port(args.http_port, "--http-port")
    scene, robot = scene_and_robot(args)
    server = viser.ViserServer(host=args.http_host, port=args.http_port, verbose=False)
    view = LiveView(server, robot, scene, args.dt, args.rate)
    client = TcpClient(args.host, args.port)
    view.attach(client)
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    try:
        client.connect(timeout=30)
    except ClientError as error:
        server.stop()
        view.approaches.close()
        return fail(
            "sim.study view", f"cannot reach the endpoint at {args.host}:{args.port}: {error}", EXIT_NO_CONNECTION
        )
    print(f"view: http://{args.http_host}:{server.get_port()} (the endpoint at {args.host}:{args.port})", flush=True)
    stop.wait()
    client.close()
    view.approaches.close()
    server.stop()
    return EXIT_OK


def _check_server_options(args: argparse.Namespace) -> None:
    check_port(args.websocket_port, "--websocket-port")
    check_port(args.port, "--port", zero=True)
    if (args.certificate is None) != (args.key is None):
        raise ViewError("--certificate and --key go together")
    if args.plain_http and args.certificate is not None:
        raise ViewError("--plain-http serves no TLS: leave out --certificate and --key")
    from sim.study.views.vr.access import is_host_name, is_loopback

    if args.plain_http and not is_loopback(args.host):
        raise ViewError(
            f"--plain-http with --host {args.host}: the key and its cookie would cross the network in clear; plain "
            "HTTP is for 127.0.0.1 or localhost only (a headset behind `adb reverse`), a LAN address needs HTTPS"
        )

    for name in args.allow_host:
        if not is_host_name(name):
            raise ViewError(
                f"--allow-host {name!r}: give a host name or an address alone, without scheme, port or path"
            )


def _serve_page(args: argparse.Namespace, site: Site, name: str) -> int:
    """Serve `site` as the options say (TLS with the given or a self-signed certificate, or plain HTTP) until
    SIGINT or SIGTERM, to the browsers that open the address it prints (with this launch's key); `name` prefixes
    what it prints. The endpoint's token and proxy secret come from the environment, out of `ps`'s sight."""
    import os
    import secrets
    import ssl

    from sim.study.views.vr.access import Access, normal_names
    from sim.study.views.vr.certificate import (
        DEFAULT_CERTIFICATE_DIR,
        ensure_certificate,
        machine_addresses,
        machine_names,
    )
    from sim.study.views.vr.relay import AUTH_TOKEN_ENV, PROXY_SECRET_ENV
    from sim.study.views.vr.server import PageServer, serve

    addresses = machine_addresses()
    tls = None
    if not args.plain_http:
        if args.certificate is not None:
            certificate, key = args.certificate, args.key
        else:
            certificate, key = ensure_certificate(args.certificate_dir or DEFAULT_CERTIFICATE_DIR, addresses)
        tls = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
        try:
            tls.load_cert_chain(certificate, key)
        except (OSError, ssl.SSLError) as error:
            raise ViewError(f"cannot use the certificate {certificate} with the key {key}: {error}") from None
    every_interface = args.host in ("0.0.0.0", "::")
    access = Access(
        secrets.token_urlsafe(18),
        normal_names([*machine_names(), *addresses, *([] if every_interface else [args.host]), *args.allow_host]),
        "http" if tls is None else "https",
    )
    server = PageServer(
        site,
        (args.endpoint_host, args.websocket_port),
        args.host,
        args.port,
        tls,
        access,
        auth_token=os.environ.get(AUTH_TOKEN_ENV) or None,
        proxy_secret=os.environ.get(PROXY_SECRET_ENV) or None,
    )

    def ready(port: int) -> None:
        hosts = ["localhost"] if args.host in ("127.0.0.1", "localhost") else ["localhost", *addresses]
        if not every_interface and args.host not in ("127.0.0.1", "localhost"):
            hosts = [args.host]
        for host in hosts:
            print(f"{name}: the page: {server.access.page_address(host, port)}", flush=True)
        token = "with the token in $" + AUTH_TOKEN_ENV if server.auth_token else "without a token"
        print(
            f"{name}: only a browser that opened this address (its key is new at each launch) reaches the endpoint; "
            f"pages are authenticated to it {token}",
            flush=True,
        )
        print(
            f"{name}: its WebSocket /ros goes to the endpoint's ws://{args.endpoint_host}:{args.websocket_port}/"
            + ("" if tls is None else "; the certificate is self-signed: accept it once in the page's browser"),
            flush=True,
        )

    try:
        serve(server, ready)
    except OSError as error:
        raise ViewError(f"cannot serve the page on {args.host}:{args.port}: {error}") from None
    return EXIT_OK


def vr_command(args: argparse.Namespace) -> int:
    from sim.robots import find_ros_package
    from sim.study.run.tracking import REST_S
    from sim.study.views.vr.site import WEB_DIR, make_site, pose_conditions_from

    _check_server_options(args)
    rest = REST_S if args.rest is None else args.rest
    check_positive(rest, "--rest")
    pose_conditions = pose_conditions_from(args.pose_conditions)
    if not (WEB_DIR / "node_modules" / "three").is_dir():
        raise ViewError(f"the page's libraries are not in {WEB_DIR / 'node_modules'}: run launch_scripts/setup.sh")
    scene, robot = scene_and_robot(args)
    site = make_site(
        robot,
        scene,
        robot.urdf_path.read_text(),
        find_ros_package,
        emulation=args.emulate_headset,
        frame_time=args.frame_time,
        pose_conditions=pose_conditions,
        rest=rest,
    )
    return _serve_page(args, site, "vr")


def button_command(args: argparse.Namespace) -> int:
    from sim.study.views.vr.site import make_button_site

    _check_server_options(args)
    return _serve_page(args, make_button_site(emulation=args.emulate_gamepad), "button")
