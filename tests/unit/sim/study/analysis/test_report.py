"""sim.study.analysis.report with the design's SESOI: the verdicts come first, then each test's mixed model as a table,
and the Bland–Altman plot beside the others; without a SESOI the report is as before."""

from __future__ import annotations

import re
from pathlib import Path

from sim.study.analysis.report import write_report
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
