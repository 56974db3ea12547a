"""sim.study.analysis.report with the design's SESOI: the verdicts come first, then each test's mixed model as a table,
and the Bland–Altman plot beside the others; without a SESOI the report is as before. A pilot's report (one
participant) has their means, and says what needs more participants, the model among it."""

from __future__ import annotations

import re
from pathlib import Path

from sim.study.analysis.mixed_model import CROSSOVER_TERMS
from sim.study.analysis.report import write_report
from tests.unit.sim.study.analysis.test_motion import tracked_study
from tests.unit.sim.study.analysis.test_summary import study


def test_the_report_gives_the_verdicts_the_model_tables_and_the_agreement_plot(tmp_path: Path) -> None:
    report = write_report(study(), tmp_path, "A study", {1: 0.05, 2: 0.02}).read_text()
    verdicts = report.index("## VR against reality: the verdicts")
    assert verdicts < report.index("## Test 1: distance perception")
    rows = [line for line in report.splitlines() if line.startswith(("| 1 | perceived", "| 2 | distance at"))]
    assert len(rows) == 2 and "**different**" in rows[0] and "| ±0.05 |" in rows[0] and "| ±0.02 |" in rows[1]
    assert "- Test 1: different: the 95 % CI [" in report
    for test in (1, 2):
        assert f"### Test {test}: the mixed model" in report
    assert re.search(r"^\| VR − reality \| -0\.1\d{3} \| 0\.\d{4} \| \[-0\.1", report, re.M)  # test 1's, about -0.15
    assert "random effects: an intercept and a condition slope per participant" in report
    assert "![agreement_bland_altman](agreement_bland_altman.png)" in report
    assert (tmp_path / "agreement_bland_altman.png").stat().st_size > 10_000


def test_without_a_sesoi_there_is_no_verdict(tmp_path: Path) -> None:
    report = write_report(study(participants=4), tmp_path).read_text()
    assert "verdict" not in report and not (tmp_path / "agreement_bland_altman.png").exists()


def test_a_pilot_of_one_participant_has_their_means_and_says_what_needs_more(tmp_path: Path) -> None:
    records = tracked_study(participants=1)
    report = write_report(records, tmp_path, "A pilot", {1: 0.05, 2: 0.02}).read_text()
    assert "A pilot of 1 participant (participant 1), 28 trials: intervals across participants, the paired" in report
    assert "## VR against reality: the verdicts" not in report and "inconclusive" not in report
    assert "95 % CI" not in report.split("## The participant's motion")[0]  # no interval, no comparison
    assert re.search(r"^\| vr \| 0\.\d{3} \|$", report, re.M) and re.search(r"^\| reality \| \d+\.\d \|$", report, re.M)
    # the model it would fit, its period and sequence named, and why it is not
    assert "## The mixed models: not fitted in a pilot" in report
    assert "needs at least 3 participants" in report
    assert "- Test 1: perceived / actual distance ~ condition × stand-off × path + period + sequence" in report
    assert "- Test 2: distance at the press (m) ~ condition × speed set × path + period + sequence" in report
    assert all(f"- {line}" in report for line in CROSSOVER_TERMS)
    # the motion (the participant's means, no pair), the latency and the plots are there
    assert re.search(r"^\| 2 \| withdrawal distance \(cm\) \| \d+\.\d \(n 1\) \| \d+\.\d \(n 1\) \| – \|", report, re.M)
    assert "test 2's withdrawal distance: 1 participant(s) with a value in both conditions, too few" in report
    assert "## Stop presses: latency" in report
    for plot in ("test1_distance_perception", "test2_comfort_distance"):
        assert f"![{plot}]({plot}.png)" in report and (tmp_path / f"{plot}.png").stat().st_size > 10_000
    assert not (tmp_path / "agreement_bland_altman.png").exists()
    # without the design's SESOIs, no model is spoken of
    assert "## The mixed models" not in write_report(records, tmp_path / "plain").read_text()
