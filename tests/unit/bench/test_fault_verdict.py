"""The fault bench's verdict (bench.fault_bench.verdict): a session that ended before the trials it was to act on is
named, as a fault not braked is, and a bench run with one never says "all faults braked"."""

from __future__ import annotations

from bench.fault_bench import Row, Session, Trial, verdict


def braked() -> Trial:
    return Trial(braked=True, short=0.2, least=0.3, recorded=0.3)


def test_every_trial_measured_and_braked_passes() -> None:
    ok, line = verdict([Row("press", "a sweep", [Session(0, [braked()] * 6, None, None, acted=6)])])
    assert ok and line.startswith("all faults braked"), line


def test_a_sweep_the_runner_ended_after_its_first_trial_fails_and_says_so() -> None:
    ok, line = verdict([Row("press", "a sweep", [Session(5, [braked()], None, None, acted=6)])])
    assert not ok and "ended early: press (1 of 6 trials; exit 5)" in line, line
