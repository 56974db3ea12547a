"""`python -m sim.study participant`: a simulated participant, a TCP client of the endpoint without rospy; and the
options of the simulated participants' known truths, which `simulate` takes too."""

from __future__ import annotations

import argparse

from sim.entry import EXIT_FAILED, EXIT_NO_CONNECTION, EXIT_OK, fail
from sim.study.checks import check_fault_trial, check_positive
from sim.study.design.options import add_scene_options, scene_and_robot
from sim.study.participants.model import KNOWN_TRUTHS, Population

__all__ = ["register", "add_fault_option", "add_population_options", "population_from_args"]


def add_population_options(command: argparse.ArgumentParser) -> None:
    truths = command.add_argument_group("the simulated participants' known truths")
    for name, meaning in KNOWN_TRUTHS.items():
        default = getattr(Population(), name)
        truths.add_argument(f"--{name.replace('_', '-')}", type=float, default=default, help=f"{meaning} ({default})")


def population_from_args(args: argparse.Namespace) -> Population:
    return Population(**{name: getattr(args, name) for name in KNOWN_TRUTHS})


def register(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    participant = commands.add_parser("participant", help="a simulated participant (TCP client of the endpoint)")
    participant.add_argument("--participant", type=int, required=True)
    participant.add_argument("--seed", type=int, required=True)
    participant.add_argument("--host", default="127.0.0.1", help="endpoint address")
    participant.add_argument("--port", type=int, default=10000, help="endpoint port")
    add_scene_options(participant)
    add_population_options(participant)
    participant.add_argument("--timeout", type=float, default=1800.0, help="give up after this many s")
    add_fault_option(participant)
    participant.set_defaults(handler=participant_command)


def add_fault_option(command: argparse.ArgumentParser) -> None:
    """--fault-trial: tests only, a fault injected into the simulated participant (`simulate` passes it on)."""
    command.add_argument(
        "--fault-trial",
        type=int,
        metavar="N",
        help="for tests only: the simulated participant measures the robot's distance at trial N (of test 1) as inf, "
        "a fault that ends it there with its error, and the simulated session with it",
    )


def participant_command(args: argparse.Namespace) -> int:
    from bridge.client import ClientError, TcpClient
    from sim.study.participants.model import draw_traits
    from sim.study.participants.simulated import SimulatedParticipant

    check_positive(args.timeout, "--timeout")
    check_positive(args.dt, "--dt")
    check_fault_trial(args.fault_trial)
    scene, robot = scene_and_robot(args)
    traits = draw_traits(population_from_args(args), args.participant, args.seed)
    client = TcpClient(args.host, args.port)
    participant = SimulatedParticipant(client, robot, scene, traits, args.seed, args.dt, args.fault_trial)
    participant.attach()
    try:
        client.connect(timeout=30)
        # The endpoint answers a ping only once it has acted on the registrations sent before it, publishers
        # advertised on the ROS graph: the runner, started once this says "connected", and its recorder then find
        # them at once. Without it the recorder's link to the last pose topic came up to a trial late.
        client.ping(timeout=30)
    except ClientError as error:
        participant.close()
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
        participant.close()
    if participant.failure:  # its own failure ends it at once, named (a crash of a part: not bad input)
        return fail("sim.study participant", participant.failure, EXIT_FAILED)
    if not finished:
        return fail("sim.study participant", f"the session did not end within {args.timeout:g} s", EXIT_NO_CONNECTION)
    print(
        f"participant {args.participant}: session done, {participant.presses} presses, "
        f"{participant.answers} questionnaire items answered"
    )
    return EXIT_OK
