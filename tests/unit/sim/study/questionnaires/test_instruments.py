"""sim.study.questionnaires.instruments: the bundled SSQ and IPQ hold the published items, keys and labels; a
malformed data file or single item is one QuestionnaireError naming the bad value."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from sim.study.errors import StudyError
from sim.study.questionnaires.errors import QuestionnaireError
from sim.study.questionnaires.instruments import (
    FOLDER,
    STANDARD,
    load_instrument,
    parse_instrument,
    single_item,
    single_item_data,
    standard_instrument,
)

SSQ = standard_instrument("ssq")
IPQ = standard_instrument("ipq")

# Kennedy et al. (1993)'s key, written out here independently of ssq.json: symptom -> clusters
SSQ_KEY = {
    "General discomfort": {"nausea", "oculomotor"},
    "Fatigue": {"oculomotor"},
    "Headache": {"oculomotor"},
    "Eye strain": {"oculomotor"},
    "Difficulty focusing": {"oculomotor", "disorientation"},
    "Increased salivation": {"nausea"},
    "Sweating": {"nausea"},
    "Nausea": {"nausea", "disorientation"},
    "Difficulty concentrating": {"nausea", "oculomotor"},
    "Fullness of head": {"disorientation"},
    "Blurred vision": {"oculomotor", "disorientation"},
    "Dizzy (eyes open)": {"disorientation"},
    "Dizzy (eyes closed)": {"disorientation"},
    "Vertigo": {"disorientation"},
    "Stomach awareness": {"nausea"},
    "Burping": {"nausea"},
}


def test_every_bundled_instrument_loads_and_cites_its_source() -> None:
    assert sorted(path.stem for path in FOLDER.glob("*.json")) == sorted(STANDARD)
    assert "Kennedy" in SSQ.about and "1993" in SSQ.about
    assert "Schubert" in IPQ.about and "igroup.org" in IPQ.about


def test_the_ssq_has_the_16_published_symptoms_in_their_clusters_on_a_0_to_3_scale() -> None:
    assert {item.text: set(item.subscales) for item in SSQ.items} == SSQ_KEY
    assert [item.text for item in SSQ.items] == list(SSQ_KEY)  # the published order
    # each cluster draws on seven symptoms
    assert all(sum(s.id in item.subscales for item in SSQ.items) == 7 for s in SSQ.subscales)
    assert {s.id: s.weight for s in SSQ.subscales} == {"nausea": 9.54, "oculomotor": 7.58, "disorientation": 13.92}
    assert SSQ.rule == "weighted_sum" and SSQ.total is not None and SSQ.total.weight == 3.74
    assert SSQ.score_ids == ("nausea", "oculomotor", "disorientation", "total")
    for item in SSQ.items:
        assert (item.low, item.high, item.points, item.reversed) == (0, 3, 4, False)
        assert [item.label(answer) for answer in range(4)] == ["none", "slight", "moderate", "severe"]


def test_the_ipq_has_14_items_in_four_subscales_three_reversed_each_with_its_own_anchors() -> None:
    expected = ["G1"] + [f"SP{k}" for k in range(1, 6)] + [f"INV{k}" for k in range(1, 5)]
    expected += [f"REAL{k}" for k in range(1, 5)]
    assert list(IPQ.item_ids) == expected
    prefix = {"G": "general_presence", "SP": "spatial_presence", "INV": "involvement", "REAL": "experienced_realism"}
    for item in IPQ.items:
        assert item.subscales == (prefix[item.id.rstrip("0123456789")],)
        assert (item.low, item.high, item.points) == (0, 6, 7)
    assert [item.id for item in IPQ.items if item.reversed] == ["SP2", "INV3", "REAL1"]
    assert IPQ.rule == "mean" and IPQ.total is None and IPQ.conditions == ("vr",)
    assert IPQ.item("G1").label(0) == "not at all" and IPQ.item("G1").label(6) == "very much"
    # the two items that read negatively keep anchors running from less to more presence, so are not reversed
    assert IPQ.item("SP3").label(6) == "felt present" and IPQ.item("INV1").label(6) == "not aware at all"
    assert IPQ.item("INV1").label(3) == "moderately aware" and IPQ.item("INV1").label(2) == ""
    # REAL1 and REAL3 ask the same question; only their anchors (and REAL1's reversal) tell them apart
    assert IPQ.item("REAL1").text == IPQ.item("REAL3").text
    assert IPQ.item("REAL1").label(0) == "completely real" and IPQ.item("REAL3").label(0).startswith("about as real")


def test_an_unknown_standard_questionnaire_or_item_is_named() -> None:
    with pytest.raises(QuestionnaireError, match="no standard questionnaire 'nasa_tlx'; known: ssq, ipq"):
        standard_instrument("nasa_tlx")
    with pytest.raises(QuestionnaireError, match="ssq has no item 'G1'"):
        SSQ.item("G1")


def ssq_data() -> dict:
    return json.loads((FOLDER / "ssq.json").read_text())


def ipq_data() -> dict:
    return json.loads((FOLDER / "ipq.json").read_text())


@pytest.mark.parametrize(
    "data, change, message",
    [
        (ssq_data, lambda d: d.pop("about"), r"missing \['about'\]"),
        (ssq_data, lambda d: d.update(version=2), r"unknown \['version'\]"),
        (ssq_data, lambda d: d.update(name="SSQ"), "name 'SSQ' must be lower case"),
        (ssq_data, lambda d: d.update(scale=[0, 20]), r"scale must have 2..11 points, got \[0, 20\]"),
        (ssq_data, lambda d: d.update(scale=[0, 2.5]), "scale must be"),
        (ssq_data, lambda d: d["labels"].pop("3"), r"item 1 \(general_discomfort\): the scale's ends 0 and 3 need"),
        (ssq_data, lambda d: d["labels"].update({"4": "awful"}), "labels: '4' is no answer on the scale 0..3"),
        (ssq_data, lambda d: d["scoring"].update(rule="median"), "scoring.rule 'median' is not one of"),
        (ssq_data, lambda d: d["subscales"][0].pop("weight"), r"subscale 1: missing \['weight'\]"),
        (ssq_data, lambda d: d["subscales"][1].update(weight=-7.58), "weight -7.58 must be a number > 0"),
        (ssq_data, lambda d: d["items"][3].update(subscales=["ocular"]), r"unknown subscale\(s\) \['ocular'\]"),
        (ssq_data, lambda d: d["items"][3].update(subscales=[]), "subscales must be a non-empty list"),
        (ssq_data, lambda d: d["items"][5].update(id="fatigue"), r"item id\(s\) \['fatigue'\] appear more"),
        (ssq_data, lambda d: d["items"][2].update(text=" "), r"item 3 \(headache\).text must be a non-empty text"),
        (ssq_data, lambda d: d["items"][2].update(reversed="yes"), "reversed must be true or false, got 'yes'"),
        (ssq_data, lambda d: d.update(items=d["items"][:1]), r"subscale\(s\) \['disorientation'\] have no item"),
        (ssq_data, lambda d: d["subscales"][0].update(id="total"), "ids repeat"),
        (ipq_data, lambda d: d["scoring"].update(total={"id": "t", "name": "T"}), "total belongs to the weighted"),
        (ipq_data, lambda d: d["subscales"][0].update(weight=2), r"subscale 1: unknown \['weight'\]; it has id, name"),
        (ipq_data, lambda d: d["items"][0]["labels"].pop("6"), r"item 1 \(G1\): the scale's ends 0 and 6 need"),
        (ipq_data, lambda d: d["items"][0].update(id="1G"), "id '1G' must be letters"),
        (ipq_data, lambda d: d.update(conditions="vr"), "conditions must be a list"),
    ],
)
def test_a_malformed_instrument_is_one_clear_error(data, change, message) -> None:
    mine = copy.deepcopy(data())
    change(mine)
    with pytest.raises(QuestionnaireError, match=message):
        parse_instrument(mine, "test.json")


def test_a_file_must_be_readable_json_named_as_its_instrument(tmp_path: Path) -> None:
    with pytest.raises(QuestionnaireError, match="cannot read the instrument"):
        load_instrument(tmp_path / "ssq.json")
    (tmp_path / "ssq.json").write_text("{")
    with pytest.raises(QuestionnaireError, match="is not JSON"):
        load_instrument(tmp_path / "ssq.json")
    (tmp_path / "sickness.json").write_text((FOLDER / "ssq.json").read_text())
    with pytest.raises(QuestionnaireError, match="name 'ssq' must be the file's, 'sickness'"):
        load_instrument(tmp_path / "sickness.json")
    assert issubclass(QuestionnaireError, StudyError)


SAFETY = {"text": "How safe did you feel near the robot?", "scale": [1, 7], "labels": ["not safe", "safe"]}


def test_a_single_item_is_an_instrument_of_one_item_scored_as_itself_and_round_trips() -> None:
    item = single_item("perceived_safety", SAFETY)
    assert item.item_ids == ("perceived_safety",) and item.score_ids == ("perceived_safety",)
    only = item.items[0]
    assert (only.low, only.high, only.points, only.reversed) == (1, 7, 7, False)
    assert only.label(1) == "not safe" and only.label(7) == "safe" and only.label(4) == ""
    assert single_item("perceived_safety", single_item_data(item)) == item
    # labels may also name points between the ends, as a mapping (digits as keys, as JSON has them, or integers)
    middle = single_item("ease", {"text": "Easy?", "scale": [0, 4], "labels": {"0": "no", 2: "so-so", "4": "yes"}})
    assert middle.items[0].labels == ((0, "no"), (2, "so-so"), (4, "yes"))
    with pytest.raises(QuestionnaireError, match="ssq is not a single item"):
        single_item_data(SSQ)


@pytest.mark.parametrize(
    "name, change, message",
    [
        ("Safety", {}, "an item's name must be lower case"),
        ("ssq", {}, "and none of ssq, ipq"),
        ("safety", {"scale": [1]}, r"safety.scale must be \[lowest, highest\]"),
        ("safety", {"scale": [7, 1]}, "must have 2..11 points"),
        ("safety", {"labels": ["only one"]}, "as a list must be the two ends' labels"),
        ("safety", {"labels": {"1": "not safe"}}, "must label both ends, 1 and 7"),
        ("safety", {"labels": {"1": "a", "7": "b", "9": "c"}}, "'9' is no answer on the scale 1..7"),
        ("safety", {"labels": ["", "safe"]}, "safety.labels.1 must be a non-empty text"),
        ("safety", {"text": None}, "safety.text must be a non-empty text, got None"),
        ("safety", {"points": 7}, r"unknown \['points'\]"),
    ],
)
def test_a_bad_single_item_is_named(name: str, change: dict, message: str) -> None:
    with pytest.raises(QuestionnaireError, match=message):
        single_item(name, {**SAFETY, **change}, "design")
