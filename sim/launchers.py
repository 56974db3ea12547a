"""The toolkit's own programs as typed launchers: each a frozen dataclass of the options it is started with, its
command line (`argv`) and the line it prints once it serves (`ready`). `start` runs one as a ManagedProcess and
returns once it is ready; `finish` waits for one to end well. The campaign, the simulated study, the tests and the
benches start the engine stand-in, the commander, the physics node, the study's runner, participant, live view and
VR page's server through here, so an option is spelled in one place.

A robot is given as its command-line arguments (RobotSpec.cli_args: `--robot PATH` and its overrides), so that a
process started from here loads the same robot as its parent.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from sim.processes import PYTHON, ManagedProcess, ProcessError, output_tail

__all__ = [
    "ButtonServer",
    "Commander",
    "Engine",
    "Launcher",
    "LiveView",
    "Participant",
    "PhysicsNode",
    "Runner",
    "VrServer",
    "finish",
    "start",
    "wait_ready",
]


class Launcher(Protocol):
    @property
    def ready(self) -> str | None:
        """What the program prints once it serves; None: it is ready once started (or runs to its end)."""

    def argv(self) -> list[str]: ...


def _option(name: str, value: object | None) -> list[str]:
    """`--name value`, or nothing for None."""
    return [] if value is None else [name, str(value)]


def _flag(name: str, given: bool) -> list[str]:
    return [name] if given else []


@dataclass(frozen=True)
class Engine:
    """`python -m sim.engine`: the game-engine stand-in, a TCP client of the endpoint at `host`:`port`; or, with
    `csv`, replaying a CSV of commands without ROS or TCP."""

    robot: Sequence[str]
    dt: float | None = None  # None: the program's default, as for every option below
    port: int | None = None
    host: str | None = None
    mode: str | None = None  # a sim.engine.physics.Mode value
    auto_simulate: bool = True  # False: lockstep, a step per /clock tick
    time_scale: float | None = None
    csv: Path | None = None
    log: Path | None = None
    extra: Sequence[str] = ()
    program = "sim.engine"

    @property
    def ready(self) -> str | None:
        return None if self.csv is not None else "connected to"

    def argv(self) -> list[str]:
        return [
            *(PYTHON, "-m", self.program, *self.robot),
            *_option("--host", self.host),
            *_option("--port", self.port),
            *_option("--mode", self.mode),
            *_option("--dt", self.dt),
            *_flag("--no-auto-simulate", not self.auto_simulate),
            *_option("--time-scale", self.time_scale),
            *_option("--csv", self.csv),
            *_option("--log", self.log),
            *self.extra,
        ]


@dataclass(frozen=True)
class PhysicsNode(Engine):
    """`python -m sim.physics_node`: the same simulation as a rospy node, with the engine's options."""

    program = "sim.physics_node"

    @property
    def ready(self) -> str | None:
        return "physics node:"


@dataclass(frozen=True)
class Commander:
    """`python -m sim.commander`: the controller (Simulink's stand-in) running `scenario` (its name and options)."""

    robot: Sequence[str]
    scenario: Sequence[str]
    dt: float | None = None
    log: Path | None = None
    wait_for: Sequence[str] = ()  # nodes (a bag recorder) that must hear every command first
    timeout: float | None = None
    realtime: bool = False
    time_scale: float | None = None
    lockstep_rate: float | None = None
    export_csv: Path | None = None
    export_only: bool = False
    extra: Sequence[str] = ()
    ready = None

    def argv(self) -> list[str]:
        return [
            *(PYTHON, "-m", "sim.commander", *self.robot, "--scenario", *self.scenario),
            *_option("--dt", self.dt),
            *_option("--log", self.log),
            *[option for node in self.wait_for for option in ("--wait-for", node)],
            *_option("--timeout", self.timeout),
            *_flag("--realtime", self.realtime),
            *_option("--time-scale", self.time_scale),
            *_option("--lockstep-rate", self.lockstep_rate),
            *_option("--export-csv", self.export_csv),
            *_flag("--export-only", self.export_only),
            *self.extra,
        ]


@dataclass(frozen=True)
class Runner:
    """`python -m sim.study run`: one participant's session of the study, from its plan into `out`."""

    plan: Path
    out: Path
    robot: Sequence[str] = ()  # the scene's and the robot's arguments
    dt: float | None = None
    realtime: bool = False
    record: bool = True
    extra: Sequence[str] = ()
    ready = None

    def argv(self) -> list[str]:
        return [
            *(PYTHON, "-m", "sim.study", "run", "--plan", str(self.plan), "--out", str(self.out)),
            *_option("--dt", self.dt),
            *_flag("--realtime", self.realtime),
            *_flag("--no-record", not self.record),
            *self.robot,
            *self.extra,
        ]


@dataclass(frozen=True)
class Participant:
    """`python -m sim.study participant`: a simulated participant, a TCP client of the endpoint on `port`."""

    participant: int
    seed: int
    port: int
    robot: Sequence[str] = ()  # the scene's and the robot's arguments
    dt: float | None = None
    truths: Sequence[str] = ()  # the population's known truths, as options
    extra: Sequence[str] = ()
    ready = "connected"

    def argv(self) -> list[str]:
        return [
            *(PYTHON, "-m", "sim.study", "participant", "--participant", str(self.participant)),
            *("--seed", str(self.seed), "--port", str(self.port)),
            *_option("--dt", self.dt),
            *self.truths,
            *self.robot,
            *self.extra,
        ]


@dataclass(frozen=True)
class LiveView:
    """`python -m sim.study view`: the observer's live 3-D view on `http_port`, of the endpoint on `port`."""

    port: int
    http_port: int
    robot: Sequence[str] = ()
    ready = "view: http"

    def argv(self) -> list[str]:
        return [
            *(PYTHON, "-m", "sim.study", "view", "--port", str(self.port), "--http-port", str(self.http_port)),
            *self.robot,
        ]


def _server_options(host: str, port: int, allow_hosts: Sequence[str], plain_http: bool) -> list[str]:
    """The page server's own options (sim.study.views.cli), the same for the VR and the button page."""
    return [
        *("--port", str(port), "--host", host),
        *[option for name in allow_hosts for option in ("--allow-host", name)],
        *_flag("--plain-http", plain_http),
    ]


@dataclass(frozen=True)
class VrServer:
    """`python -m sim.study vr`: the VR page's server on `host`:`port` (0: a free one), passing the page's WebSocket
    to the endpoint's `websocket_port`; `certificate_dir` holds its self-signed certificate. The endpoint's token and
    proxy secret go in its environment (sim.study.views.vr.relay's AUTH_TOKEN_ENV, PROXY_SECRET_ENV), not here."""

    websocket_port: int
    port: int = 0
    host: str = "127.0.0.1"
    certificate_dir: Path | None = None
    allow_hosts: Sequence[str] = ()  # names the page may be opened by beyond the machine's own
    plain_http: bool = False
    emulate_headset: bool = False  # and the tests' probe
    frame_time: bool = False  # the frame-time instrument, for the bench
    robot: Sequence[str] = ()
    extra: Sequence[str] = ()
    ready = "its WebSocket /ros goes to"

    def argv(self) -> list[str]:
        return [
            *(PYTHON, "-m", "sim.study", "vr", "--websocket-port", str(self.websocket_port)),
            *_server_options(self.host, self.port, self.allow_hosts, self.plain_http),
            *_option("--certificate-dir", self.certificate_dir),
            *_flag("--emulate-headset", self.emulate_headset),
            *_flag("--frame-time", self.frame_time),
            *self.robot,
            *self.extra,
        ]

    @staticmethod
    def page_url(output: str) -> str:
        """The page's address (with this launch's key), from the server's output once it is ready."""
        return next(line.split("the page: ")[1] for line in output.splitlines() if "the page: " in line)


@dataclass(frozen=True)
class ButtonServer:
    """`python -m sim.study button`: the stop button's page on `host`:`port` (0: a free one), served like the VR
    page's; `emulate_gamepad` loads the emulated gamepad and the tests' probe."""

    websocket_port: int
    port: int = 0
    host: str = "127.0.0.1"
    certificate_dir: Path | None = None
    allow_hosts: Sequence[str] = ()
    plain_http: bool = False
    emulate_gamepad: bool = False
    extra: Sequence[str] = ()
    ready = "its WebSocket /ros goes to"

    def argv(self) -> list[str]:
        return [
            *(PYTHON, "-m", "sim.study", "button", "--websocket-port", str(self.websocket_port)),
            *_server_options(self.host, self.port, self.allow_hosts, self.plain_http),
            *_option("--certificate-dir", self.certificate_dir),
            *_flag("--emulate-gamepad", self.emulate_gamepad),
            *self.extra,
        ]

    page_url = staticmethod(VrServer.page_url)


def start(
    launcher: Launcher,
    env: dict[str, str],
    log_dir: Path,
    name: str,
    prefix: Sequence[str] = (),
    timeout: float = 60.0,
    wait: bool = True,
) -> ManagedProcess:
    """Start `launcher`'s program (in `prefix`, e.g. a network namespace) and return once it is ready (see
    `wait_ready`); `wait=False` returns at once, for starting several programs side by side."""
    process = ManagedProcess(launcher.argv(), env, log_dir, name, prefix)
    if wait:
        wait_ready(process, launcher, timeout)
    return process


def wait_ready(process: ManagedProcess, launcher: Launcher, timeout: float = 60.0) -> None:
    """Return once `process` printed `launcher`'s ready line; if it does not within `timeout` s, it is stopped and
    ProcessError says why, with its output's tail."""
    if launcher.ready is None:
        return
    try:
        process.wait_for_output(launcher.ready, timeout=timeout)
    except BaseException:
        process.stop()
        raise


def finish(process: ManagedProcess, timeout: float) -> str:
    """Wait up to `timeout` s for `process` to end; its output. ProcessError, naming its log and showing the
    output's tail, when it fails or is still running."""
    code = process.wait(timeout)
    if code != 0:
        raise ProcessError(f"{process.name} exited with {code}; its log: {process.log_path}\n{output_tail(process)}")
    return process.output()
