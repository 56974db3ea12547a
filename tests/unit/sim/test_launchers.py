"""sim.launchers: each launcher's command line is one its program's own parser accepts, with the values given."""

from __future__ import annotations

from pathlib import Path

import pytest

from sim.control.commander import _parser as commander_parser
from sim.engine.stand_in import argument_parser as engine_parser
from sim.launchers import ButtonServer, Commander, Engine, LiveView, Participant, PhysicsNode, Runner, VrServer
from sim.processes import PYTHON
from sim.study.__main__ import parser as study_parser

ROBOT = ("--robot", "panda", "--ee-link", "panda_hand")


def program_args(argv: list[str], program: str) -> list[str]:
    assert argv[:3] == [PYTHON, "-m", program]
    return argv[3:]


def test_the_engine_in_lockstep_on_an_endpoint() -> None:
    engine = Engine(ROBOT, 0.02, port=10001, host="10.0.0.2", mode="no_physics", auto_simulate=False)
    args = engine_parser().parse_args(program_args(engine.argv(), "sim.engine"))
    assert (args.robot, args.ee_link, args.port, args.host, args.dt) == ("panda", "panda_hand", 10001, "10.0.0.2", 0.02)
    assert args.no_auto_simulate and args.mode == "no_physics" and args.csv is None
    assert engine.ready == "connected to"


def test_the_engine_replaying_a_csv_runs_to_its_end() -> None:
    engine = Engine(ROBOT, csv=Path("in.csv"), log=Path("out.csv"), time_scale=5.0, extra=("--duration", "3"))
    args = engine_parser().parse_args(program_args(engine.argv(), "sim.engine"))
    assert (args.csv, args.log, args.time_scale, args.duration) == (Path("in.csv"), Path("out.csv"), 5.0, 3.0)
    assert not args.no_auto_simulate and "--port" not in engine.argv()
    assert engine.ready is None


def test_the_physics_node_takes_the_engines_options() -> None:
    node = PhysicsNode(ROBOT, auto_simulate=False)
    args = engine_parser().parse_args(program_args(node.argv(), "sim.physics_node"))
    assert args.no_auto_simulate and node.ready == "physics node:"


def test_the_commander_with_its_recorder_and_wall_clock() -> None:
    commander = Commander(
        ROBOT, ("sweep",), 0.02, log=Path("c.csv"), wait_for=("rec",), timeout=30, realtime=True, time_scale=5.0
    )
    args = commander_parser().parse_args(program_args(commander.argv(), "sim.commander"))
    assert (args.scenario, args.dt, args.log, args.wait_for, args.timeout) == (
        "sweep",
        0.02,
        Path("c.csv"),
        ["rec"],
        30,
    )
    assert args.realtime and args.time_scale == 5.0 and not args.export_only
    exporting = Commander(ROBOT, ("sweep",), export_csv=Path("d.csv"), export_only=True)
    args = commander_parser().parse_args(program_args(exporting.argv(), "sim.commander"))
    assert args.export_only and args.export_csv == Path("d.csv") and not args.realtime
    paced = Commander(ROBOT, ("sweep",), lockstep_rate=250.0)
    args = commander_parser().parse_args(program_args(paced.argv(), "sim.commander"))
    assert args.lockstep_rate == 250.0 and not args.realtime


@pytest.mark.parametrize(
    ("launcher", "expected"),
    [
        (Runner(Path("p.yaml"), Path("out"), ROBOT, 0.02, realtime=True, record=False), {"realtime": True}),
        (Participant(3, 7, 10001, ("--scene", "s.yaml"), 0.02, ("--vr-distance-shift=0.05",)), {"seed": 7}),
        (LiveView(10001, 8080, ROBOT), {"http_port": 8080}),
        (VrServer(9090, certificate_dir=Path("certs"), emulate_headset=True, frame_time=True), {"frame_time": True}),
        (ButtonServer(9091, certificate_dir=Path("c"), emulate_gamepad=True), {"emulate_gamepad": True, "port": 0}),
        (
            VrServer(9090, allow_hosts=("vr.lab.example", "labpc"), plain_http=True),
            {"allow_host": ["vr.lab.example", "labpc"], "plain_http": True, "host": "127.0.0.1"},
        ),
    ],
)
def test_the_studys_programs(
    launcher: Runner | Participant | LiveView | VrServer | ButtonServer, expected: dict[str, object]
) -> None:
    args = study_parser().parse_args(program_args(launcher.argv(), "sim.study"))
    assert {key: getattr(args, key) for key in expected} == expected
    assert launcher.ready is None or isinstance(launcher.ready, str)
    if isinstance(launcher, Runner):
        assert (args.plan, args.out, args.dt, args.no_record, args.robot) == (
            Path("p.yaml"),
            Path("out"),
            0.02,
            True,
            "panda",
        )
    if isinstance(launcher, Participant):
        assert (args.participant, args.port, args.scene, args.vr_distance_shift) == (3, 10001, Path("s.yaml"), 0.05)


def test_the_vr_servers_page_address_is_read_from_its_output() -> None:
    output = "vr: the page: https://localhost:8443/\nvr: its WebSocket /ros goes to the endpoint's ws://x:9090/\n"
    assert VrServer.page_url(output) == "https://localhost:8443/"
    button = "button: the page: https://localhost:8444/\nbutton: its WebSocket /ros goes to the endpoint's ws://x:1/\n"
    assert ButtonServer.page_url(button) == "https://localhost:8444/"
