"""sim.study.analysis.questionnaires: the scores per administration, the SSQ's change from before to after VR per
participant, the participants whose VR data are suspect (SSQ total after VR above the threshold), read from the
folder the runner writes, and the report's section."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import pytest

from sim.study.analysis.errors import AnalysisError
from sim.study.analysis.questionnaires import (
    SSQ_SUSPECT_TOTAL,
    load_questionnaires,
    questionnaire_lines,
    summarise_questionnaires,
)
from sim.study.analysis.report import write_report
from sim.study.questionnaires.instruments import single_item, standard_instrument
from sim.study.questionnaires.rows import score_rows
from sim.study.run.questionnaires import scores_path, write_questionnaire
from tests.unit.sim.study.analysis.test_summary import study

SSQ = standard_instrument("ssq")
SAFETY = single_item("perceived_safety", {"text": "Safe?", "scale": [1, 7], "labels": ["no", "yes"]})


def ssq(level: int) -> dict[str, int]:
    return dict.fromkeys(SSQ.item_ids, level)


def rows():
    """Participant 1: no symptoms before, all slight after VR (total 3.74 x 21 = 78.54); participant 2: none either
    time; participant 3: after VR only, one symptom moderate (nausea: N and D, raw 2 each, total 3.74 x 4 = 14.96)."""
    return [
        *score_rows(1, SSQ, "ssq_before_vr", ssq(0)),
        *score_rows(1, SSQ, "ssq_after_vr", ssq(1)),
        *score_rows(2, SSQ, "ssq_before_vr", ssq(0)),
        *score_rows(2, SSQ, "ssq_after_vr", ssq(0)),
        *score_rows(3, SSQ, "ssq_after_vr", {**ssq(0), "nausea": 2}),
        *score_rows(1, SAFETY, "perceived_safety_after_reality", {"perceived_safety": 6}),
        *score_rows(2, SAFETY, "perceived_safety_after_reality", {"perceived_safety": 3}),
        *score_rows(1, SAFETY, "perceived_safety_after_vr", {"perceived_safety": 5}),
    ]


def test_scores_are_summarised_per_administration_in_the_order_asked() -> None:
    summary = summarise_questionnaires(rows())
    found = {(s.administration, s.subscale): s for s in summary.scores}
    total = found[("ssq_after_vr", "total")]
    assert total.n == 3 and total.mean == pytest.approx((78.54 + 0 + 14.96) / 3)
    assert total.sd == pytest.approx(math.sqrt(sum((x - total.mean) ** 2 for x in (78.54, 0, 14.96)) / 2))
    assert found[("ssq_before_vr", "nausea")].mean == 0.0
    safety = found[("perceived_safety_after_reality", "perceived_safety")]
    assert (safety.n, safety.mean, safety.sd) == (2, 4.5, pytest.approx(math.sqrt(4.5)))
    assert math.isnan(found[("perceived_safety_after_vr", "perceived_safety")].sd)  # one participant
    order = list(dict.fromkeys(s.administration for s in summary.scores))
    assert order == ["ssq_before_vr", "ssq_after_vr", "perceived_safety_after_vr", "perceived_safety_after_reality"]
    assert [s.subscale for s in summary.scores[:4]] == ["nausea", "oculomotor", "disorientation", "total"]


def test_the_ssqs_change_and_who_was_sick_after_vr() -> None:
    summary = summarise_questionnaires(rows())
    assert [(c.participant, c.before, c.after) for c in summary.ssq[:2]] == [
        (1, 0.0, pytest.approx(78.54)),
        (2, 0.0, 0.0),
    ]
    third = summary.ssq[2]
    assert third.participant == 3 and math.isnan(third.before) and math.isnan(third.change)
    assert summary.suspect == (1,) and summary.threshold == SSQ_SUSPECT_TOTAL == 20.0
    assert summarise_questionnaires(rows(), threshold=10.0).suspect == (1, 3)
    lines = "\n".join(questionnaire_lines(summary))
    assert "## Questionnaires" in lines
    assert "| 1 | 0.0 | 78.5 | +78.5 | **VR data suspect** |" in lines
    assert "| 3 | – | 15.0 | – | |" in lines
    assert "| ssq_after_vr | total | 3 | 31.17 (" in lines
    assert "Mean change +39.3 over 2 participants." in lines
    assert "above 20: participant(s) 1." in lines and "convention, not a clinical cut-off" in lines
    assert questionnaire_lines(summarise_questionnaires([])) == []
    calm = summarise_questionnaires([r for r in rows() if r.participant == 2])
    assert "above 20: no participant." in "\n".join(questionnaire_lines(calm))


def test_the_scores_are_read_from_the_folder_the_runner_writes(tmp_path: Path) -> None:
    assert load_questionnaires(tmp_path) == []  # a study that asked none
    write_questionnaire(tmp_path, 1, SSQ, {"ssq_before_vr": ssq(0), "ssq_after_vr": ssq(1)})
    write_questionnaire(tmp_path, 2, SSQ, {"ssq_after_vr": ssq(2)})
    write_questionnaire(tmp_path, 1, SAFETY, {"perceived_safety_after_vr": {"perceived_safety": 4}})
    loaded = load_questionnaires(tmp_path)
    assert len(loaded) == 4 + 4 + 4 + 1
    assert summarise_questionnaires(loaded).suspect == (1, 2)
    shutil.copy(scores_path(tmp_path, "ssq", 2), scores_path(tmp_path, "ssq", 2).with_name("copy.csv"))
    with pytest.raises(AnalysisError, match="participant 2's ssq_after_vr disorientation is scored more than once"):
        load_questionnaires(tmp_path)
    scores_path(tmp_path, "ssq", 2).with_name("copy.csv").write_text("nonsense\n")
    with pytest.raises(AnalysisError, match="the header must be"):
        load_questionnaires(tmp_path)


def test_the_report_has_the_section_before_its_plots(tmp_path: Path) -> None:
    report = write_report(study(participants=4), tmp_path, questionnaires=summarise_questionnaires(rows()))
    text = report.read_text()
    assert text.index("## Test 2: comfort distance") < text.index("## Questionnaires") < text.index("## Plots")
    assert "**VR data suspect**" in text
    assert "## Questionnaires" not in write_report(study(participants=4), tmp_path / "plain").read_text()
