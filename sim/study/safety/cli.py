"""`python -m sim.study check --safety`: before a real arm moves, every combination of the design (planned and checked
by the design's `check`) against the robot's limits with a declared margin, its braking from a press at any sample
too, the move to its start from home and from any rest on a path (start_moves.py), no planned point closer to the
hand than a declared floor, and the speed and separation rule (separation.py) letting every plan reach its stand-off
with the hand resting, a stop stamped the lead's ceiling ahead. One line per refusal, naming the limit; exit 2 when
there is one. Otherwise it says which limits were held and, where a kind of limit is unknown for the robot, what was
not checked. The toolkit's own check: it never replaces the robot's own stop."""

from __future__ import annotations

import argparse
import math

from sim.entry import EXIT_OK
from sim.study.checks import check_positive
from sim.study.safety.errors import SafetyError

__all__ = ["register"]


def register(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Adds the safety options to the design's `check` (registered before this)."""
    check = commands.choices["check"]
    check.add_argument(
        "--safety",
        action="store_true",
        help="before a real arm: also refuse samples or braking beyond the robot's limits (--margin) and the --floor",
    )
    check.add_argument("--margin", type=float, default=0.8, help="--safety: the fraction of each limit a plan may use")
    check.add_argument("--floor", type=float, default=0.01, help="--safety: m no planned point may come to the hand")
    check.add_argument("--deceleration", type=float, default=1.0, help="--safety: braking on a press, m/s² on the path")
    check.add_argument(
        "--lead",
        type=float,
        default=None,
        help="--safety: s a stop is stamped ahead: the separation rule's reaction time (default: the stop lead's "
        "ceiling, the longest the link stamps a stop ahead)",
    )
    check.add_argument(
        "--hand-speed",
        type=float,
        default=0.0,
        help="--safety: m/s the hand may close on the robot while it approaches; 0: the hand rests on its mark, as "
        "a tracked, still hand does (the separation rule then asks only the stand-off to clear floor + C + Z)",
    )
    check.set_defaults(handler=safety_check_command)


def safety_check_command(args: argparse.Namespace) -> int:
    from sim.study.design.cli import checked_combinations
    from sim.study.safety.check import design_refusals
    from sim.study.safety.limits import coverage, limits_for
    from sim.study.safety.separation import STOP_LEAD_CEILING, SeparationParameters
    from sim.study.safety.start_moves import start_move_refusals

    if args.lead is None:
        args.lead = STOP_LEAD_CEILING
    if args.safety:  # the margin and floor are said before the planning's minute, not after
        check_positive(args.deceleration, "--deceleration")
        if not (0 < args.margin <= 1):
            raise SafetyError(f"--margin must be in (0, 1], got {args.margin!r}")
        if not (args.floor >= 0):
            raise SafetyError(f"--floor must be >= 0 m, got {args.floor!r}")
        if not (0 <= args.lead < math.inf):
            raise SafetyError(f"--lead must be >= 0 s, got {args.lead!r}")
        if not (0 <= args.hand_speed < math.inf):
            raise SafetyError(f"--hand-speed must be >= 0 m/s, got {args.hand_speed!r}")
        separation = SeparationParameters(floor=args.floor, deceleration=args.deceleration)
    robot, approaches = checked_combinations(args)
    if not args.safety:
        return EXIT_OK
    limits = limits_for(robot)
    refusals = design_refusals(
        limits, approaches, args.margin, args.floor, args.deceleration, separation, args.lead, args.hand_speed
    )
    refusals += start_move_refusals(robot, limits, approaches, args.margin)
    for line in refusals:
        print(f"refused: {line}")
    if refusals:
        raise SafetyError(
            f"{len(refusals)} refusal(s); to change: lower peak speeds, a gentler --deceleration, a larger stand-off, "
            "a shorter measured --lead"
        )
    within, unchecked = coverage(robot.name, limits, args.margin)
    print(f"{within}, floor {args.floor:g} m" + (f"; not checked: {unchecked}" if unchecked else ""))
    print(
        "motions checked: each approach's samples, its braking from a press at any sample, and the move to its start "
        "from home and from any rest on an approach's path (not from an arm left elsewhere than home)"
    )
    print(
        f"the separation rule (C+Z {separation.allowances:g} m, lead {args.lead:g} s, hand {args.hand_speed:g} m/s) "
        "lets every plan reach its stand-off"
    )
    return EXIT_OK
