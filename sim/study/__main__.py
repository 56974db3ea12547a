"""python -m sim.study: plan, check, run, simulate and analyse the perception study (docs/study.md).

  plan --participant N --seed S [--out PLAN.yaml] [--print]   a participant's session plan (counterbalanced)
  check [--safety --margin 0.8 --floor 0.01]                   every combination of the design planned and checked
  scene --robot URDF [--out SCENE.yaml]                       a scene that fits the robot, proposed and checked
  run --plan PLAN.yaml --out DIR [--realtime] [--auto-go]     the runner node: executes the plan (ROS)
  participant --port P --participant N --seed S               a simulated participant (a TCP client, no rospy)
  view --port P [--http-port 8080]                            the experimenter's live 3-D view (a web page)
  vr --websocket-port W [--port 8443]                         the VR condition's page for a WebXR headset (HTTPS)
  button --websocket-port W [--port 8444]                     reality's stop button page: a USB button, pedal, gamepad
  tracker --config YAML --participant N --out DIR             a tracker calibrated into the scene, relayed (ROS)
  analyse DIR [--out DIR] [--design D]                        the report (verdicts, models) over every CSV in DIR
  simulate --participants 12 --out DIR                        the whole study with simulated participants, end to end
  power --test 2 [--difference D --sd-between S ...]          the sample size, from studies simulated without physics
  preregister [--design D] [--out FILE]                       the pre-registration summary, from the design file

Each subcommand lives with its concern (its package's cli module); this only wires them. Bad input (an unknown path
name, an infeasible combination, a malformed plan or scene) is one line and exit 2.
"""

from __future__ import annotations

import argparse
import sys

from sim.entry import EXIT_BAD_INPUT, fail
from sim.errors import SimError
from sim.study.analysis import cli as analysis_cli
from sim.study.design import cli as design_cli
from sim.study.participants import cli as participants_cli
from sim.study.power import cli as power_cli
from sim.study.run import cli as run_cli
from sim.study.safety import cli as safety_cli
from sim.study.simulation import cli as simulation_cli
from sim.study.views import cli as views_cli

__all__ = ["main"]

# in the order the help lists them: from the design to the sample size
REGISTERS = (
    design_cli.register,
    safety_cli.register,  # its options on the design's check
    run_cli.register,
    participants_cli.register,
    views_cli.register,
    analysis_cli.register,
    simulation_cli.register,
    power_cli.register,
)


def parser() -> argparse.ArgumentParser:
    made = argparse.ArgumentParser(prog="python -m sim.study", description=__doc__.splitlines()[0])
    commands = made.add_subparsers(dest="command", required=True)
    for register in REGISTERS:
        register(commands)
    return made


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        return args.handler(args)
    except SimError as error:  # a design, scene, plan, robot or number that cannot be used
        return fail(f"sim.study {args.command}", error, EXIT_BAD_INPUT)


if __name__ == "__main__":
    sys.exit(main())
