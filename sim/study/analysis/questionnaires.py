"""The questionnaires' part of the report: every score CSV the runner wrote (questionnaires/scores/ in the study's
folder), summarised per administration; the SSQ's change from before to after VR per participant; and who was sick
enough after VR that their VR data is suspect. Pure logic, but for `load_questionnaires`.

The threshold: the grading of SSQ totals commonly attributed to Kennedy and colleagues (Stanney, Kennedy & Drexler
1997, "Cybersickness is not simulator sickness", Proc. HFES 41(2); Kennedy et al. 2003) reads a total above 20 as a
"bad" simulator. That grade is for a simulator's mean over its users; applying it to one participant's total after
VR is a convention of this study, not a clinical cut-off. The participant's data stay in every analysis; the report
names them, so that the analysis can be repeated without them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.study.analysis.errors import AnalysisError
from sim.study.design.spec import CONDITIONS, POSITIONS
from sim.study.errors import StudyError
from sim.study.questionnaires.rows import ScoreRow, read_scores

__all__ = [
    "SSQ_SUSPECT_TOTAL",
    "SSQ_SUSPECT_SOURCE",
    "ScoreSummary",
    "SicknessChange",
    "QuestionnaireSummary",
    "load_questionnaires",
    "summarise_questionnaires",
    "questionnaire_lines",
]

SSQ_SUSPECT_TOTAL = 20.0  # an SSQ total after VR above this: the participant's VR data are suspect
SSQ_SUSPECT_SOURCE = (
    "The grading of SSQ totals after Kennedy and colleagues (e.g. Stanney, Kennedy & Drexler 1997) reads a total "
    'above 20 as a "bad" simulator; that grade is for a simulator\'s mean, and applying it to one participant is '
    "this study's convention, not a clinical cut-off"
)


@dataclass(frozen=True)
class ScoreSummary:
    questionnaire: str
    administration: str
    subscale: str
    n: int  # participants
    mean: float
    sd: float  # sample SD; NaN for a single participant


@dataclass(frozen=True)
class SicknessChange:
    participant: int
    before: float  # SSQ total before VR; NaN when not scored
    after: float  # SSQ total after VR; NaN when not scored

    @property
    def change(self) -> float:
        return self.after - self.before


@dataclass(frozen=True)
class QuestionnaireSummary:
    scores: tuple[ScoreSummary, ...]  # by when asked (before, after; VR, reality), questionnaire, subscale
    ssq: tuple[SicknessChange, ...]  # per participant with an SSQ total before or after VR
    suspect: tuple[int, ...]  # the participants whose SSQ total after VR is above the threshold
    threshold: float


def load_questionnaires(directory: Path) -> list[ScoreRow]:
    """Every score row in `directory`/questionnaires/scores/*.csv (none when the study asked none); AnalysisError
    when a file cannot be read or one score appears twice."""
    rows: list[ScoreRow] = []
    for path in sorted((Path(directory) / "questionnaires" / "scores").glob("*.csv")):
        try:
            rows += read_scores(path)
        except StudyError as error:
            raise AnalysisError(str(error)) from None
    keys = [(row.participant, row.administration, row.subscale) for row in rows]
    repeated = sorted({key for key in keys if keys.count(key) > 1})
    if repeated:
        participant, administration, subscale = repeated[0]
        raise AnalysisError(f"participant {participant}'s {administration} {subscale} is scored more than once")
    return rows


def _when(administration: str) -> tuple[int, int]:
    """Where an administration (<name>_<position>_<condition>) comes: before before after, VR before reality."""
    _, position, condition = administration.rsplit("_", 2)
    return (
        POSITIONS.index(position) if position in POSITIONS else len(POSITIONS),
        CONDITIONS.index(condition) if condition in CONDITIONS else len(CONDITIONS),
    )


def summarise_questionnaires(rows: list[ScoreRow], threshold: float = SSQ_SUSPECT_TOTAL) -> QuestionnaireSummary:
    names = list(dict.fromkeys(row.questionnaire for row in rows))  # in the order first found
    groups: dict[tuple[str, str, str], list[float]] = {}
    for row in rows:
        groups.setdefault((row.questionnaire, row.administration, row.subscale), []).append(row.score)
    subscales = list(dict.fromkeys(row.subscale for row in rows))  # each instrument's in its own order
    # when asked first (before, after; VR, reality), so that a questionnaire before a block comes before one after
    order = sorted(groups, key=lambda k: (_when(k[1]), names.index(k[0]), k[1], subscales.index(k[2])))
    scores = tuple(
        ScoreSummary(
            *key,
            len(groups[key]),
            float(np.mean(groups[key])),
            float(np.std(groups[key], ddof=1)) if len(groups[key]) > 1 else math.nan,
        )
        for key in order
    )
    totals = {
        (row.participant, row.administration): row.score
        for row in rows
        if row.questionnaire == "ssq" and row.subscale == "total"
    }
    participants = sorted({p for p, administration in totals if administration in ("ssq_before_vr", "ssq_after_vr")})
    ssq = tuple(
        SicknessChange(p, totals.get((p, "ssq_before_vr"), math.nan), totals.get((p, "ssq_after_vr"), math.nan))
        for p in participants
    )
    suspect = tuple(change.participant for change in ssq if change.after > threshold)
    return QuestionnaireSummary(scores, ssq, suspect, threshold)


def _number(value: float, digits: int = 1, sign: str = "") -> str:
    return "–" if math.isnan(value) else f"{value:{sign}.{digits}f}"


def questionnaire_lines(summary: QuestionnaireSummary) -> list[str]:
    """The report's section, in markdown; nothing when no questionnaire was scored."""
    if not summary.scores:
        return []
    lines = [
        "## Questionnaires",
        "",
        "Scores by the published keys (SSQ: Kennedy et al. 1993, weighted clusters and total; IPQ: Schubert et al. "
        "2001, subscale means, 0..6), per administration across participants: mean (SD). An administration with an "
        "item unanswered is not scored (its answers are in questionnaires/answers/).",
        "",
        "| administration | score | n | mean (SD) |",
        "|---|---|---|---|",
    ]
    lines += [
        f"| {s.administration} | {s.subscale} | {s.n} | {s.mean:.2f} ({_number(s.sd, 2)}) |" for s in summary.scores
    ]
    if summary.ssq:
        lines += [
            "",
            "The SSQ total before and after VR, per participant:",
            "",
            "| participant | before VR | after VR | change | |",
            "|---|---|---|---|---|",
        ]
        lines += [
            f"| {c.participant} | {_number(c.before)} | {_number(c.after)} | {_number(c.change, 1, '+')} | "
            + ("**VR data suspect** |" if c.participant in summary.suspect else "|")
            for c in summary.ssq
        ]
        changes = [c.change for c in summary.ssq if not math.isnan(c.change)]
        if changes:
            lines += ["", f"Mean change {np.mean(changes):+.1f} over {len(changes)} participants."]
        lines += ["", f"**VR data suspect** when the SSQ total after VR is above {summary.threshold:g}: "]
        lines[-1] += (
            f"participant(s) {', '.join(str(p) for p in summary.suspect)}. " if summary.suspect else "no participant. "
        )
        lines[-1] += f"{SSQ_SUSPECT_SOURCE}. Their data stay in the analyses above."
    return [*lines, ""]
