"""python -m sim.study: plan, check, run, simulate and analyse the perception study (docs/study.md).

  plan --participant N --seed S [--out PLAN.yaml] [--print]   a participant's session plan (counterbalanced)
  check                                                       every combination of the design planned and checked
  run --plan PLAN.yaml --out DIR [--realtime] [--auto-go]     the runner node: executes the plan (ROS)
  participant --port P --participant N --seed S               a simulated participant (a TCP client, no rospy)
  vr --websocket-port W [--port 8443]                          the VR condition's page for a WebXR headset (HTTPS)
  analyse DIR [--out DIR] [--design D]                        the report (verdicts, models) over every CSV in DIR
  simulate --participants 12 --out DIR                        the whole study with simulated participants, end to end
  power --test 2 [--difference D --sd-between S ...]          the sample size, from studies simulated without physics
  preregister [--design D] [--out FILE]                       the pre-registration summary, from the design file

Bad input (an unknown path name, an infeasible combination, a malformed plan or scene) is one line and exit 2.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import yaml

from sim.entry import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_NO_CONNECTION, EXIT_OK, fail
from sim.errors import SimError
from sim.robots import RobotSpec, add_robot_overrides, overrides_from_args
from sim.study.design import TESTS, load_design
from sim.study.errors import StudyError
from sim.study.participant_model import KNOWN_TRUTHS, Population
from sim.study.plan import make_plan, plan_from_data, plan_to_data, printable
from sim.study.scene import Scene, load_scene, scene_robot
from sim.study.yamlfile import read_yaml
from sim.wire.contract import STEP_S

__all__ = ["main"]


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m sim.study", description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)

    def with_robot(command: argparse.ArgumentParser) -> None:
        command.add_argument("--scene", type=Path, help="scene YAML (default: the bundled scene.yaml)")
        robot = command.add_argument_group("robot (default: the scene's, with its ee_link)")
        robot.add_argument("--robot", help="a URDF path, a robot YAML path or a bundled name, in the scene's place")
        add_robot_overrides(robot)

    def with_scene(command: argparse.ArgumentParser) -> None:
        with_robot(command)
        command.add_argument("--dt", type=float, default=STEP_S, help=f"control step in s (default {STEP_S})")

    def with_population(command: argparse.ArgumentParser) -> None:
        truths = command.add_argument_group("the simulated participants' known truths")
        for name, meaning in KNOWN_TRUTHS.items():
            default = getattr(Population(), name)
            truths.add_argument(
                f"--{name.replace('_', '-')}", type=float, default=default, help=f"{meaning} ({default})"
            )

    plan = commands.add_parser("plan", help="a participant's session plan")
    plan.add_argument("--participant", type=int, required=True)
    plan.add_argument("--seed", type=int, required=True)
    plan.add_argument("--design", type=Path, help="design YAML (default: the bundled design.yaml)")
    plan.add_argument("--out", type=Path, help="write the plan here (default: print it as YAML)")
    plan.add_argument("--print", action="store_true", help="print the observer's table instead of YAML")

    check = commands.add_parser("check", help="plan and check every combination of the design")
    check.add_argument("--design", type=Path, help="design YAML (default: the bundled design.yaml)")
    with_scene(check)

    run = commands.add_parser("run", help="the runner node: execute a plan")
    run.add_argument("--plan", type=Path, required=True)
    run.add_argument("--out", type=Path, required=True, help="the participant's CSV, bag and logs go here")
    with_scene(run)
    run.add_argument("--realtime", action="store_true", help="pace by the wall clock (VR headset, real robot)")
    run.add_argument("--auto-go", action="store_true", help="start each approach at once, without waiting for go")
    run.add_argument(
        "--keyboard",
        action="store_true",
        help="the observer types here: Enter = go, s = stop, distances and preferences when asked",
    )
    run.add_argument("--no-record", action="store_true", help="no rosbag record")
    run.add_argument("--settle", type=float, default=0.5, help="s held after each motion before it is at rest")
    run.add_argument("--deceleration", type=float, default=1.0, help="braking on a press, m/s² along the path")
    run.add_argument(
        "--response-timeout",
        type=float,
        default=300.0,
        help="longest wait for go or an answer in s; then the trial goes on without it (default 300)",
    )
    run.add_argument("--step-timeout", type=float, default=10.0, help="lockstep: longest wait for a joint state")
    run.add_argument("--connect-timeout", type=float, default=60.0, help="longest wait for the engine at start")

    participant = commands.add_parser("participant", help="a simulated participant (TCP client of the endpoint)")
    participant.add_argument("--participant", type=int, required=True)
    participant.add_argument("--seed", type=int, required=True)
    participant.add_argument("--host", default="127.0.0.1", help="endpoint address")
    participant.add_argument("--port", type=int, default=10000, help="endpoint port")
    with_scene(participant)
    with_population(participant)
    participant.add_argument("--timeout", type=float, default=1800.0, help="give up after this many s")

    view = commands.add_parser("view", help="the experimenter's live 3-D view, a web page (viser)")
    view.add_argument("--host", default="127.0.0.1", help="endpoint address")
    view.add_argument("--port", type=int, default=10000, help="endpoint port")
    view.add_argument("--http-host", default="127.0.0.1", help="the page's address (0.0.0.0: every interface)")
    view.add_argument("--http-port", type=int, default=8080, help="the page's port (default 8080)")
    view.add_argument("--rate", type=float, default=20.0, help="page updates per second at most (default 20)")
    with_scene(view)

    vr = commands.add_parser("vr", help="the VR condition's page for a WebXR headset (docs/study.md)")
    vr.add_argument("--endpoint-host", default="127.0.0.1", help="the endpoint's address")
    vr.add_argument("--websocket-port", type=int, default=9090, help="the endpoint's --websocket-port (default 9090)")
    vr.add_argument("--host", default="0.0.0.0", help="the page's address (default 0.0.0.0: every interface)")
    vr.add_argument("--port", type=int, default=8443, help="the page's port (default 8443; 0 picks a free one)")
    vr.add_argument(
        "--plain-http",
        action="store_true",
        help="HTTP without TLS: only for a browser on this machine or behind `adb reverse` (localhost is secure)",
    )
    vr.add_argument("--certificate", type=Path, help="your own TLS certificate (PEM), with --key")
    vr.add_argument("--key", type=Path, help="the key of --certificate (PEM)")
    vr.add_argument(
        "--certificate-dir",
        type=Path,
        help="where the self-signed certificate is made once and kept (default ~/.ros/sim_study_vr)",
    )
    vr.add_argument(
        "--emulate-headset",
        action="store_true",
        help="load an emulated Quest 3 (IWER) in the page: for tests and for trying the page without a headset",
    )
    with_robot(vr)

    analyse = commands.add_parser("analyse", help="the report over every participant's CSV in a directory")
    analyse.add_argument("directory", type=Path, help="where the participant_*.csv files are")
    analyse.add_argument("--out", type=Path, help="where report.md and the plots go (default: the directory)")
    analyse.add_argument("--design", type=Path, help="the design whose SESOIs judge VR (default: the bundled one)")

    simulate = commands.add_parser("simulate", help="the whole study with simulated participants, end to end")
    simulate.add_argument("--participants", type=int, default=12)
    simulate.add_argument("--out", type=Path, required=True, help="plans, CSVs, bags, logs, report.md and plots")
    simulate.add_argument("--seed", type=int, default=1)
    simulate.add_argument("--design", type=Path, help="design YAML (default: the bundled design.yaml)")
    with_scene(simulate)
    with_population(simulate)

    power = commands.add_parser("power", help="the sample size: whole studies simulated from the participant model")
    power.add_argument("--test", type=int, choices=TESTS, required=True)
    power.add_argument("--difference", type=float, help="the true VR - reality, in the measure's units")
    power.add_argument("--sd-between", type=float, help="the SD of the participants' own VR - reality differences")
    power.add_argument("--sesoi", type=float, help="the smallest effect size of interest (default: the design's)")
    power.add_argument("--participants", help="numbers of participants to simulate, comma-separated (e.g. 8,12,16)")
    power.add_argument("--simulations", type=int, help="simulated studies per number of participants")
    power.add_argument("--seed", type=int)
    power.add_argument("--design", type=Path, help="design YAML whose planning gives the defaults (default: bundled)")
    power.add_argument(
        "--json", type=Path, help="write the rows here (a list `rows` of participants, p_different, ...)"
    )
    power.add_argument("--plot", type=Path, help="the power curve (default: beside --json, else power_test<T>.png)")
    power.add_argument("--workers", type=int, default=0, help="processes (default: one per core, at most 2)")

    preregister = commands.add_parser("preregister", help="the pre-registration summary (Markdown) from the design")
    preregister.add_argument("--design", type=Path, help="design YAML, with its planning (default: the bundled one)")
    preregister.add_argument("--out", type=Path, help="write the Markdown here (default: print it)")
    preregister.add_argument("--participants", help="sizes to try, comma-separated (default: the design's planning)")
    preregister.add_argument("--simulations", type=int, help="studies per size (default: the design's planning)")
    preregister.add_argument("--workers", type=int, default=0, help="processes (default: one per core, at most 2)")
    return parser


def _robot(scene: Scene, args: argparse.Namespace) -> RobotSpec:
    """The robot of a command: the scene's, or the one --robot names; the overrides on top."""
    return scene_robot(scene, args.robot, overrides_from_args(args))


def _population(args: argparse.Namespace) -> Population:
    return Population(**{name: getattr(args, name) for name in KNOWN_TRUTHS})


def _check_positive(value: float, option: str) -> None:
    if not value > 0:
        raise StudyError(f"{option} must be > 0, got {value}")


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    commands = {
        "plan": _plan,
        "check": _check,
        "run": _run,
        "participant": _participant,
        "view": _view,
        "vr": _vr,
        "analyse": _analyse,
        "simulate": _simulate,
        "power": _power,
        "preregister": _preregister,
    }
    try:
        return commands[args.command](args)
    except SimError as error:  # a design, scene, plan, robot or number that cannot be used
        return fail(f"sim.study {args.command}", error, EXIT_BAD_INPUT)


def _plan(args: argparse.Namespace) -> int:
    plan = make_plan(load_design(args.design), args.participant, args.seed)
    text = printable(plan) if args.print else yaml.safe_dump(plan_to_data(plan), sort_keys=False)
    if args.out is None:
        print(text, end="")
    else:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
        print(
            f"plan of participant {plan.participant}: {len(plan.trials)} trials, {' then '.join(plan.conditions)}"
            f" -> {args.out}"
        )
    return EXIT_OK


def _check(args: argparse.Namespace) -> int:
    from sim.study.feasibility import plan_combinations

    _check_positive(args.dt, "--dt")
    design, scene = load_design(args.design), load_scene(args.scene)
    robot = _robot(scene, args)
    plan = make_plan(design, 1, 0)
    started = time.monotonic()
    approaches = plan_combinations(robot, scene, [(t.path, t.standoff, t.peak_speed) for t in plan.trials], args.dt)
    elapsed = time.monotonic() - started
    print("| path | stand-off | peak speed | samples | duration | clearance table / hand | verdict |")
    print("|---|---|---|---|---|---|---|")
    for (path, standoff, speed), planned in approaches.items():
        clearance = planned.min_clearance
        verdict = "feasible" if planned.feasible else "; ".join(planned.problems)
        print(
            f"| {path} | {standoff:.3f} m | {speed:.2f} m/s | {len(planned.path.times)} | "
            f"{planned.path.duration:.2f} s | {clearance['table'] * 1000:.0f} / {clearance['hand'] * 1000:.0f} mm | "
            f"{verdict} |"
        )
    print(f"{len(approaches)} combinations planned in {elapsed:.1f} s")
    infeasible = [key for key, planned in approaches.items() if not planned.feasible]
    if infeasible:
        raise StudyError(
            f"{len(infeasible)} combination(s) of the design are not feasible: "
            f"{', '.join(f'{p} to {s} m at {v} m/s' for p, s, v in infeasible)}"
        )
    return EXIT_OK


def _run(args: argparse.Namespace) -> int:
    from sim.control.stepper import Pacing
    from sim.study.feasibility import plan_combinations
    from sim.study.runner import RunnerOptions, run_node

    for option in ("dt", "settle", "deceleration", "response_timeout", "step_timeout", "connect_timeout"):
        _check_positive(getattr(args, option), f"--{option.replace('_', '-')}")
    plan = plan_from_data(read_yaml(args.plan, "plan"), str(args.plan))
    scene = load_scene(args.scene)
    robot = _robot(scene, args)
    approaches = plan_combinations(robot, scene, [(t.path, t.standoff, t.peak_speed) for t in plan.trials], args.dt)
    infeasible = {key: planned.problems for key, planned in approaches.items() if not planned.feasible}
    if infeasible:
        raise StudyError(
            "the plan has combinations that are not feasible (none was run): "
            + "; ".join(f"{p} to {s} m at {v} m/s: {', '.join(problems)}" for (p, s, v), problems in infeasible.items())
        )
    options = RunnerOptions(
        Pacing(args.dt, args.realtime, step_timeout=args.step_timeout),
        args.auto_go,
        args.keyboard,
        args.settle,
        args.response_timeout,
        args.deceleration,
    )
    return run_node(
        robot, scene, plan, approaches, options, args.out.resolve(), not args.no_record, args.connect_timeout
    )


def _participant(args: argparse.Namespace) -> int:
    from bridge.client import ClientError, TcpClient
    from sim.study.participant import SimulatedParticipant
    from sim.study.participant_model import draw_traits

    _check_positive(args.timeout, "--timeout")
    _check_positive(args.dt, "--dt")
    scene = load_scene(args.scene)
    robot = _robot(scene, args)
    traits = draw_traits(_population(args), args.participant, args.seed)
    client = TcpClient(args.host, args.port)
    participant = SimulatedParticipant(client, robot, scene, traits, args.seed, args.dt)
    participant.attach()
    try:
        client.connect(timeout=30)
    except ClientError as error:
        return fail(
            "sim.study participant",
            f"cannot reach the endpoint at {args.host}:{args.port}: {error}",
            EXIT_NO_CONNECTION,
        )
    print(f"participant {args.participant}: connected; {participant.traits_note}", flush=True)
    try:
        finished = participant.done.wait(args.timeout)
    finally:
        client.close()
    for problem in participant.problems:
        print(f"sim.study participant: {problem}", file=sys.stderr)
    if not finished:
        return fail("sim.study participant", f"the session did not end within {args.timeout:g} s", EXIT_NO_CONNECTION)
    print(f"participant {args.participant}: session done, {participant.presses} presses")
    return EXIT_OK if not participant.problems else EXIT_FAILED


def _view(args: argparse.Namespace) -> int:
    import signal
    import threading

    import viser

    from bridge.client import ClientError, TcpClient
    from sim.study.view import LiveView

    _check_positive(args.rate, "--rate")
    _check_positive(args.dt, "--dt")
    if not 0 < args.http_port < 65536:
        raise StudyError(f"--http-port must be 1..65535, got {args.http_port}")
    scene = load_scene(args.scene)
    robot = _robot(scene, args)
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
        return fail(
            "sim.study view", f"cannot reach the endpoint at {args.host}:{args.port}: {error}", EXIT_NO_CONNECTION
        )
    print(f"view: http://{args.http_host}:{server.get_port()} (the endpoint at {args.host}:{args.port})", flush=True)
    stop.wait()
    client.close()
    server.stop()
    return EXIT_OK


def _port(value: int, option: str, zero: bool = False) -> None:
    if not (0 if zero else 1) <= value <= 65535:
        raise StudyError(f"{option} must be {0 if zero else 1}..65535, got {value}")


def _vr(args: argparse.Namespace) -> int:
    import ssl

    from sim.robots import find_ros_package
    from sim.study.vr.certificate import DEFAULT_CERTIFICATE_DIR, ensure_certificate, machine_addresses
    from sim.study.vr.server import PageServer, serve
    from sim.study.vr.site import WEB_DIR, make_site

    _port(args.websocket_port, "--websocket-port")
    _port(args.port, "--port", zero=True)
    if (args.certificate is None) != (args.key is None):
        raise StudyError("--certificate and --key go together")
    if args.plain_http and args.certificate is not None:
        raise StudyError("--plain-http serves no TLS: leave out --certificate and --key")
    if not (WEB_DIR / "node_modules" / "three").is_dir():
        raise StudyError(f"the page's libraries are not in {WEB_DIR / 'node_modules'}: run launch_scripts/setup.sh")
    scene = load_scene(args.scene)
    robot = _robot(scene, args)
    site = make_site(robot, scene, robot.urdf_path.read_text(), find_ros_package, emulation=args.emulate_headset)
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
            raise StudyError(f"cannot use the certificate {certificate} with the key {key}: {error}") from None
    server = PageServer(site, (args.endpoint_host, args.websocket_port), args.host, args.port, tls)

    def ready(port: int) -> None:
        scheme = "http" if tls is None else "https"
        hosts = ["localhost"] if args.host in ("127.0.0.1", "localhost") else ["localhost", *addresses]
        if args.host not in ("0.0.0.0", "127.0.0.1", "localhost"):
            hosts = [args.host]
        for host in hosts:
            print(f"vr: the page: {scheme}://{host}:{port}/", flush=True)
        print(
            f"vr: its WebSocket /ros goes to the endpoint's ws://{args.endpoint_host}:{args.websocket_port}/"
            + ("" if tls is None else "; the certificate is self-signed: accept it once in the headset's browser"),
            flush=True,
        )

    try:
        serve(server, ready)
    except OSError as error:
        raise StudyError(f"cannot serve the page on {args.host}:{args.port}: {error}") from None
    return EXIT_OK


def _analyse(args: argparse.Namespace) -> int:
    from sim.study.report import load_study, write_report

    sesoi = load_design(args.design).sesoi
    report = write_report(load_study(args.directory), args.out or args.directory, sesoi=sesoi)
    print(report.read_text(), end="")
    print(f"report: {report}")
    return EXIT_OK


def _simulate(args: argparse.Namespace) -> int:
    from sim.study.simulate import Simulation, SimulationError, simulate

    _check_positive(args.dt, "--dt")
    if args.seed < 0:
        raise StudyError(f"--seed must be >= 0, got {args.seed}")
    started = time.monotonic()
    settings = Simulation(
        args.participants,
        args.seed,
        args.out,
        args.design,
        args.scene,
        args.dt,
        _population(args),
        robot=args.robot,
        robot_overrides=overrides_from_args(args),
    )
    try:
        report = simulate(settings, lambda line: print(f"simulate: {line}", flush=True))
    except SimulationError as error:
        return fail("sim.study simulate", error, EXIT_FAILED)
    print(report.read_text(), end="")
    print(f"simulate: {args.participants} participants in {time.monotonic() - started:.0f} s; report: {report}")
    return EXIT_OK


def _participant_counts(text: str) -> tuple[int, ...]:
    try:
        return tuple(int(part) for part in text.split(","))
    except ValueError:
        raise StudyError(f"--participants must be whole numbers separated by commas, got {text!r}") from None


def _check_workers(workers: int) -> None:
    if not 0 <= workers <= 64:
        raise StudyError(f"--workers must be 0..64 (0: one per core, at most 2), got {workers}")


def _preregister(args: argparse.Namespace) -> int:
    import hashlib

    from tqdm import tqdm

    from sim.study.design import DEFAULT_DESIGN
    from sim.study.power import plan_sample, planned_questions
    from sim.study.preregistration import preregistration

    _check_workers(args.workers)
    source = DEFAULT_DESIGN if args.design is None else args.design
    design = load_design(source)
    digest = hashlib.sha256(Path(source).read_bytes()).hexdigest()
    sizes = None if args.participants is None else _participant_counts(args.participants)
    # before the progress bar: a design without planning, or a bad --simulations, is one line
    questions = planned_questions(design, sizes, args.simulations)
    with tqdm(desc="simulated studies", unit="study", file=sys.stderr, mininterval=1.0) as bar:
        sample = plan_sample(design, questions, args.workers, progress=bar.update)
    text = preregistration(design, str(source), digest, sample)
    if args.out is None:
        print(text, end="")
    else:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
        planned = "none of the sizes tried" if sample.participants is None else f"{sample.participants} participants"
        print(f"pre-registration: {args.out} (planned: {planned})")
    return EXIT_OK


def _power(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from sim.study.power import PowerQuestion, power_rows
    from sim.study.power_report import plot_power, power_data, power_table

    design, test = load_design(args.design), args.test
    given: dict[str, Any] = {
        "difference": args.difference,
        "sd_between": args.sd_between,
        "participants": None if args.participants is None else _participant_counts(args.participants),
        "simulations": args.simulations,
        "seed": args.seed,
    }
    planning = design.planning
    planned: dict[str, Any] = (
        {}
        if planning is None
        else {
            "difference": planning.expected_difference[test],
            "sd_between": planning.sd_between[test],
            "participants": planning.participants,
            "simulations": planning.simulations,
            "seed": planning.seed,
        }
    )
    missing = [f"--{name.replace('_', '-')}" for name, value in given.items() if value is None and name not in planned]
    if missing:
        raise StudyError(f"{', '.join(missing)} needed: the design has no planning section to take them from")
    chosen = {name: planned[name] if value is None else value for name, value in given.items()}
    question = PowerQuestion(
        test=test,
        difference=float(chosen["difference"]),
        sd_between=float(chosen["sd_between"]),
        sesoi=design.sesoi[test] if args.sesoi is None else args.sesoi,
        participants=tuple(chosen["participants"]),
        simulations=int(chosen["simulations"]),
        seed=int(chosen["seed"]),
    )
    _check_workers(args.workers)
    plot = args.plot or (args.json.with_suffix(".png") if args.json is not None else Path(f"power_test{test}.png"))
    started = time.monotonic()
    total = question.simulations * len(question.participants)
    with tqdm(total=total, desc="simulated studies", unit="study", file=sys.stderr, mininterval=1.0) as bar:
        rows = power_rows(question, design, workers=args.workers, progress=bar.update)
    seconds = time.monotonic() - started
    print(power_table(question, rows), end="")
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(power_data(question, rows, seconds), indent=2) + "\n")
        print(f"rows: {args.json}")
    print(f"power curve: {plot_power(question, rows, plot)}")
    print(f"power: {total} simulated studies in {seconds:.1f} s")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
