"""sim.control.commander without ROS: its options, checked once, and the export that touches no ROS."""

from __future__ import annotations

from pathlib import Path

import pytest

from sim.control.commander import CommanderOptions, _parser, main, options_from_args
from sim.control.stepper import Pacing
from sim.wire.contract import PoseConvention


def _args(*extra: str):
    return _parser().parse_args(["--robot", "panda", "--scenario", "single", *extra])


def test_the_command_line_becomes_one_options_value() -> None:
    options = options_from_args(
        _args("--dt", "0.01", "--realtime", "--time-scale", "2", "--timeout", "3", "--pose-convention", "euler")
    )
    assert options == CommanderOptions(
        pacing=Pacing(dt=0.01, realtime=True, time_scale=2.0, step_timeout=3.0),
        pose_convention=PoseConvention.EULER,
    )
    assert options_from_args(_args("--lockstep-rate", "250")).pacing == Pacing(lockstep_rate=250.0)


@pytest.mark.parametrize(
    "flags, message",
    [
        (("--timeout", "0"), "--timeout must be > 0"),
        (("--connect-timeout", "nan"), "--connect-timeout must be > 0"),
        (("--time-scale", "-1"), "--time-scale must be > 0"),
        (("--approach", "-0.5"), "--approach must be >= 0 s"),
        (("--lockstep-rate", "0"), "--lockstep-rate must be > 0 steps a second"),
        (("--lockstep-rate", "inf"), "--lockstep-rate must be > 0 steps a second"),
        (("--lockstep-rate", "100", "--realtime"), "--lockstep-rate paces lockstep: with --realtime"),
    ],
)
def test_a_bad_run_option_is_one_line_and_exit_2(flags, message, capsys) -> None:
    assert main(["--robot", "panda", "--scenario", "single", *flags]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_the_old_name_of_the_sweep_still_exports_with_a_warning(tmp_path: Path, capsys) -> None:
    out = tmp_path / "desired.csv"
    argv = ["--robot", "panda", "--scenario", "trial", "--export-csv", str(out), "--export-only", "--duration", "1"]
    assert main(argv) == 0
    assert "sim.commander: warning: scenario 'trial' is now 'sweep'" in capsys.readouterr().err
    assert len(out.read_text().splitlines()) == 1 + 51  # header + 1 s at 0.02 s
