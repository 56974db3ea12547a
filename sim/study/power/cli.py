"""`python -m sim.study power` (the sample size, from studies simulated without physics) and `preregister` (the
pre-registration summary, from the design file)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from sim.entry import EXIT_OK
from sim.study.checks import check_workers, participant_counts
from sim.study.design.options import add_design_option
from sim.study.design.spec import TESTS, load_design
from sim.study.power.errors import PowerError

__all__ = ["register"]


def register(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    power = commands.add_parser("power", help="the sample size: whole studies simulated from the participant model")
    power.add_argument("--test", type=int, choices=TESTS, required=True)
    power.add_argument("--difference", type=float, help="the true VR - reality, in the measure's units")
    power.add_argument("--sd-between", type=float, help="the SD of the participants' own VR - reality differences")
    power.add_argument("--sesoi", type=float, help="the smallest effect size of interest (default: the design's)")
    power.add_argument("--participants", help="numbers of participants to simulate, comma-separated (e.g. 8,12,16)")
    power.add_argument("--simulations", type=int, help="simulated studies per number of participants")
    power.add_argument("--seed", type=int)
    add_design_option(power, "design YAML whose planning gives the defaults (default: bundled)")
    power.add_argument(
        "--json", type=Path, help="write the rows here (a list `rows` of participants, p_different, ...)"
    )
    power.add_argument("--plot", type=Path, help="the power curve (default: beside --json, else power_test<T>.png)")
    power.add_argument("--workers", type=int, default=0, help="processes (default: one per core, at most 2)")
    power.set_defaults(handler=power_command)

    preregister = commands.add_parser("preregister", help="the pre-registration summary (Markdown) from the design")
    add_design_option(preregister, "design YAML, with its planning (default: the bundled one)")
    preregister.add_argument("--out", type=Path, help="write the Markdown here (default: print it)")
    preregister.add_argument("--participants", help="sizes to try, comma-separated (default: the design's planning)")
    preregister.add_argument("--simulations", type=int, help="studies per size (default: the design's planning)")
    preregister.add_argument("--workers", type=int, default=0, help="processes (default: one per core, at most 2)")
    preregister.set_defaults(handler=preregister_command)


def preregister_command(args: argparse.Namespace) -> int:
    import hashlib

    from tqdm import tqdm

    from sim.study.design.spec import DEFAULT_DESIGN
    from sim.study.power.preregistration import preregistration
    from sim.study.power.sample_size import plan_sample, planned_questions

    check_workers(args.workers)
    source = DEFAULT_DESIGN if args.design is None else args.design
    design = load_design(source)
    digest = hashlib.sha256(Path(source).read_bytes()).hexdigest()
    sizes = None if args.participants is None else participant_counts(args.participants)
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


def power_command(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from sim.study.power.report import plot_power, power_data, power_table
    from sim.study.power.sample_size import PowerQuestion, power_rows

    design, test = load_design(args.design), args.test
    given: dict[str, Any] = {
        "difference": args.difference,
        "sd_between": args.sd_between,
        "participants": None if args.participants is None else participant_counts(args.participants),
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
        raise PowerError(f"{', '.join(missing)} needed: the design has no planning section to take them from")
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
    check_workers(args.workers)
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
