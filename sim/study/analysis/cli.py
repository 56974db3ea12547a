"""`python -m sim.study analyse DIR`: the report (verdicts, models, questionnaires, plots) over every participant's
CSV in DIR (and their questionnaires' scores in DIR/questionnaires/scores)."""

from __future__ import annotations

import argparse
from pathlib import Path

from sim.entry import EXIT_OK
from sim.study.design.options import add_design_option
from sim.study.design.spec import load_design

__all__ = ["register"]


def register(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    analyse = commands.add_parser("analyse", help="the report over every participant's CSV in a directory")
    analyse.add_argument("directory", type=Path, help="where the participant_*.csv files are")
    analyse.add_argument("--out", type=Path, help="where report.md and the plots go (default: the directory)")
    add_design_option(analyse, "the design whose SESOIs judge VR (default: the bundled one)")
    analyse.set_defaults(handler=analyse_command)


def analyse_command(args: argparse.Namespace) -> int:
    from sim.study.analysis.questionnaires import load_questionnaires, summarise_questionnaires
    from sim.study.analysis.report import load_study, write_report
    from sim.study.analysis.trackers import load_trackers, summarise_trackers

    sesoi = load_design(args.design).sesoi
    questionnaires = summarise_questionnaires(load_questionnaires(args.directory))
    report = write_report(
        load_study(args.directory),
        args.out or args.directory,
        sesoi=sesoi,
        questionnaires=questionnaires,
        trackers=summarise_trackers(load_trackers(args.directory)),
    )
    print(report.read_text(), end="")
    print(f"report: {report}")
    return EXIT_OK
