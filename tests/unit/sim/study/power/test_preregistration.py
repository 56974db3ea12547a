"""sim.study.power.preregistration and sample_size.plan_sample: the summary says what the design declares (hypotheses,
measures, the participant's motion as secondary measures, SESOIs with their reasons, the planned N and its power, the
models at the trial level, the missing trials' sensitivity analysis, the decision rules), and the sample is the first
size at which every test reaches the planned power."""

from __future__ import annotations

import copy

import pytest
import yaml

from sim.study.design.spec import DEFAULT_DESIGN, parse_design
from sim.study.errors import StudyError
from sim.study.power.preregistration import preregistration
from sim.study.power.sample_size import PlannedSample, PowerRow, plan_sample, planned_questions

DATA = yaml.safe_load(DEFAULT_DESIGN.read_text())


def design_with(**planning: object):
    data = copy.deepcopy(DATA)
    data["planning"].update(planning)
    return parse_design(data)


def test_the_sample_is_the_first_size_at_which_both_tests_reach_the_power():
    easy = design_with(sd_between={"test1": 0.005, "test2": 0.002}, participants=[6, 8, 12])
    sample = plan_sample(easy, planned_questions(easy, simulations=20), workers=1)
    assert sample.participants == 6  # tiny differences between people: the smallest size is enough
    assert [row.participants for row in sample.rows[1]] == [6] and sample.simulations == 20
    hard = design_with(sd_between={"test1": 0.3, "test2": 0.1}, participants=[6, 8])
    sample = plan_sample(hard, planned_questions(hard, simulations=20), workers=1)
    assert sample.participants is None and [row.participants for row in sample.rows[2]] == [6, 8]
    data = copy.deepcopy(DATA)
    del data["planning"]
    with pytest.raises(StudyError, match="no planning section"):
        planned_questions(parse_design(data))


def test_the_summary_declares_what_the_analysis_will_judge_by():
    design = parse_design(DATA)
    rows = {
        1: [PowerRow(12, 500, 0.05, 0.62, 0.0), PowerRow(16, 500, 0.05, 0.83, 0.0)],
        2: [PowerRow(12, 500, 0.04, 0.91, 0.0), PowerRow(16, 500, 0.05, 0.97, 0.0)],
    }
    text = preregistration(design, "design.yaml", "ab" * 32, PlannedSample(16, rows, 500, 1))
    for expected in (
        "SHA-256 `" + "ab" * 32 + "`",
        "lies within ±0.05 (equivalence)",
        "lies within ±0.02 m (equivalence)",
        "| 2 | ±0.02 m | Comfort distances spread by several centimetres",
        "**Planned: 16 participants.**",
        "| 16 | 0.830 | 0.050 |",
        "distance at the press (m) ~ condition × speed set × path + period + sequence",
        "perceived / actual distance ~ condition × stand-off × path + period + sequence",
        "Carry-over cannot be estimated",
        "- `button` (in reality): the participant's button in reality",
        "- `keyboard` (in neither condition: flagged)",
        "- **Simulator Sickness Questionnaire** (`ssq`, 16 items), before VR, after VR; scored as each subscale's raw "
        "sum weighted (Nausea × 9.54, Oculomotor × 7.58, Disorientation × 13.92); Total score: 3.74 × the sum",
        "(`ipq`, 14 items), after VR; scored as the mean of each subscale's items",
        "SP2, INV3, REAL1 reversed",
        "(`perceived_safety`, 1 item), after VR, after reality; scored as its answer",
        "SSQ total after VR is above 20 is named in the report",
        "**equivalent** when its 90 % confidence interval lies inside ±SESOI",
        "**different** when its 95 % confidence interval excludes 0",
        "true VR − reality +0, SD of the participants' own differences 0.06",
        "38 trials per participant",
        "## The participant's motion (secondary, exploratory)",
        "- `/study/pose/head`: the headset, between the eyes",
        "- `/study/pose/left_hand`: ",
        "- `/study/pose/right_hand`: ",
        "each a `geometry_msgs/PoseStamped` in the `world` frame",
        "the experimenter touches at least 4 marked points of the table and the hand model, not all in one plane",
        "a fit whose largest residual is above the bound the configuration declares is refused",
        "tracker's jitter (the RMS distance of a body's positions from their mean while it is held still)",
        "Each trial records the tracker that tracked it and its calibration (the headset worn in reality",
        "where a participant's conditions were not tracked by one tracker with one calibration, every VR − reality",
        "- **withdrawal distance** (`withdrawal_distance`): how far the hand under the robot got away from the robot",
        "- **withdrawal peak speed** (`withdrawal_peak_speed`)",
        "- **head to the end effector at the press** (`head_distance_at_press`)",
        "poses further apart than 0.1 s leave a gap in its tracking",
        "test 2's withdrawal distance, withdrawal peak speed, head to the end effector at the press and test 1's "
        "withdrawal distance",
        "withdrawal distance (m) ~ condition × speed set × path + period + sequence",
        "no equivalence margin is declared for them and no verdict is drawn",
        # the primary analysis at the trial level, and the missing trials' sensitivity analysis beside it
        "fitted at the trial level to every trial with a measure, never to per-participant means",
        "## Missing trials",
        "unbiased when the trials are missing at random given those (MAR)",
        "Sensitivity analysis (delta-adjusted multiple imputation, a pattern-mixture model): each missing trial is "
        "imputed 10 times",
        "each condition's missing trials shifted by −SESOI and +SESOI (seed 59)",
        "Secondary and descriptive, reported beside the verdicts: the paired TOST",
    ):
        assert expected in text, expected
    none = preregistration(design, "design.yaml", "0" * 64, PlannedSample(None, rows, 500, 1))
    assert "more than 16 participants are needed" in none


def test_a_sesoi_reason_must_be_text():
    data = copy.deepcopy(DATA)
    data["test1"]["sesoi_reason"] = 5
    with pytest.raises(StudyError, match="test1.sesoi_reason must be text"):
        parse_design(data)
    del data["test1"]["sesoi_reason"]
    assert 1 not in parse_design(data).sesoi_reason
