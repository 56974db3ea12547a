"""The instruments as data, read and checked. A standard instrument is a JSON file beside this module (ssq.json,
ipq.json): its source, the instruction, the answer scale and its labels, each item with the subscales it belongs to
and whether it is reversed, and how it is scored. The lab's own single items come from the design (`single_item`).
Pure logic, but for reading those files.

Everything an item is asked with is here, because answering is one item at a time (the headset's panel, the
observer's keyboard): the text, the scale's lowest and highest answer, and the labels of at least those two."""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from sim.study.questionnaires.errors import QuestionnaireError

__all__ = [
    "FOLDER",
    "STANDARD",
    "RULES",
    "MAX_POINTS",
    "Item",
    "Subscale",
    "Instrument",
    "parse_instrument",
    "load_instrument",
    "standard_instrument",
    "is_name",
    "single_item",
    "single_item_data",
]

FOLDER = Path(__file__).resolve().parent
STANDARD = ("ssq", "ipq")  # the bundled instruments, each in <name>.json in FOLDER
# weighted_sum: a subscale's score is its weight x the sum of its items' scores (the SSQ's key); mean: the mean of
# its items' scores (the IPQ's, and a single item's own answer)
RULES = ("weighted_sum", "mean")
MAX_POINTS = 11  # a scale of more points is no longer one a participant steps through with a thumbstick
_NAME = re.compile(r"[a-z][a-z0-9_]*\Z")  # instrument names go into administrations and file names as they are
_ITEM_ID = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")  # the IPQ's published codes (G1, SP1, ...) are capitals
_INTEGER = re.compile(r"-?[0-9]+\Z")


@dataclass(frozen=True)
class Item:
    id: str
    text: str
    low: int  # the lowest answer
    high: int  # the highest answer
    labels: tuple[tuple[int, str], ...]  # (answer, its label), increasing; always the low and the high end
    subscales: tuple[str, ...]  # the ids of the subscales it counts in (an SSQ symptom may count in two)
    reversed: bool = False  # scored as low + high - answer

    @property
    def points(self) -> int:
        return self.high - self.low + 1

    def label(self, answer: int) -> str:
        """The label of `answer` on this item's scale, or "" where the scale has none."""
        return dict(self.labels).get(answer, "")


@dataclass(frozen=True)
class Subscale:
    id: str
    name: str
    weight: float = 1.0  # weighted_sum: the score is weight x the raw sum; mean: unused


@dataclass(frozen=True)
class Instrument:
    name: str  # ssq, ipq, or a single item's id
    title: str
    about: str  # where it comes from: the citation
    instruction: str  # what the participant reads before the first item ("" for a single item)
    items: tuple[Item, ...]  # in the order they are asked
    subscales: tuple[Subscale, ...]
    rule: str  # one of RULES
    total: Subscale | None = None  # weighted_sum only: its weight x the sum of every subscale's raw sum
    conditions: tuple[str, ...] = ()  # the conditions it may be given in; () for any

    def item(self, item_id: str) -> Item:
        for item in self.items:
            if item.id == item_id:
                return item
        raise QuestionnaireError(f"{self.name} has no item {item_id!r}; its items: {', '.join(self.item_ids)}")

    @property
    def item_ids(self) -> tuple[str, ...]:
        return tuple(item.id for item in self.items)

    @property
    def score_ids(self) -> tuple[str, ...]:
        """What scoring gives, in order: each subscale, then the total if there is one."""
        return tuple(s.id for s in self.subscales) + ((self.total.id,) if self.total else ())


def is_name(value: object) -> bool:
    """Whether `value` can name an instrument: lower case, digits and _, starting with a letter."""
    return isinstance(value, str) and bool(_NAME.match(value))


def _text(value: object, where: str) -> str:
    if not (isinstance(value, str) and value.strip()):
        raise QuestionnaireError(f"{where} must be a non-empty text, got {value!r}")
    return " ".join(value.split())


def _integer(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _scale(value: object, where: str) -> tuple[int, int]:
    if not (isinstance(value, list) and len(value) == 2 and all(_integer(v) for v in value)):
        raise QuestionnaireError(f"{where} must be [lowest, highest] answer as two integers, got {value!r}")
    low, high = value
    if not 2 <= high - low + 1 <= MAX_POINTS:
        raise QuestionnaireError(f"{where} must have 2..{MAX_POINTS} points, got {value!r}")
    return low, high


def _labels(value: object, low: int, high: int, where: str) -> dict[int, str]:
    """Labels as given: {answer: label} (answers as integers, or as digits where JSON makes keys text), or
    [label of low, label of high]."""
    if isinstance(value, list):
        if len(value) != 2:
            raise QuestionnaireError(f"{where} as a list must be the two ends' labels, got {value!r}")
        value = {low: value[0], high: value[1]}
    if not isinstance(value, dict):
        raise QuestionnaireError(f"{where} must map answers to labels, got {value!r}")
    labels = {}
    for key, label in value.items():
        answer = int(key) if isinstance(key, str) and _INTEGER.match(key) else key
        if not (_integer(answer) and low <= answer <= high):
            raise QuestionnaireError(f"{where}: {key!r} is no answer on the scale {low}..{high}")
        labels[answer] = _text(label, f"{where}.{key}")
    return labels


def _keys(data: object, required: tuple[str, ...], optional: tuple[str, ...], where: str) -> dict[str, Any]:
    if not isinstance(data, dict):
        raise QuestionnaireError(f"{where} must be a mapping, got {data!r}")
    missing = [key for key in required if key not in data]
    unknown = [key for key in data if key not in required + optional]
    if missing or unknown:
        problems = ([f"missing {missing}"] if missing else []) + ([f"unknown {unknown}"] if unknown else [])
        raise QuestionnaireError(
            f"{where}: {', '.join(problems)}; it has {', '.join(required)}"
            + (f" and optionally {', '.join(optional)}" if optional else "")
        )
    return data


def _subscale(data: object, rule: str, where: str) -> Subscale:
    entry = _keys(data, ("id", "name", "weight") if rule == "weighted_sum" else ("id", "name"), (), where)
    if not is_name(entry["id"]):
        raise QuestionnaireError(f"{where}: id {entry['id']!r} must be lower case letters, digits and _")
    weight = entry.get("weight", 1.0)
    if not (isinstance(weight, (int, float)) and not isinstance(weight, bool) and math.isfinite(weight) and weight > 0):
        raise QuestionnaireError(f"{where}: weight {weight!r} must be a number > 0")
    return Subscale(entry["id"], _text(entry["name"], f"{where}.name"), float(weight))


def _item(data: object, low: int, high: int, default_labels: dict[int, str], subscales: list[str], where: str) -> Item:
    entry = _keys(data, ("id", "text", "subscales"), ("labels", "reversed"), where)
    if not (isinstance(entry["id"], str) and _ITEM_ID.match(entry["id"])):
        raise QuestionnaireError(f"{where}: id {entry['id']!r} must be letters, digits and _, starting with a letter")
    where = f"{where} ({entry['id']})"
    labels = dict(default_labels)
    labels.update(_labels(entry["labels"], low, high, f"{where}.labels") if "labels" in entry else {})
    if low not in labels or high not in labels:
        raise QuestionnaireError(f"{where}: the scale's ends {low} and {high} need labels, got {labels!r}")
    member = entry["subscales"]
    if not (isinstance(member, list) and member and len(set(member)) == len(member)):
        raise QuestionnaireError(f"{where}: subscales must be a non-empty list without repeats, got {member!r}")
    unknown = [name for name in member if name not in subscales]
    if unknown:
        raise QuestionnaireError(f"{where}: unknown subscale(s) {unknown}; the instrument's: {', '.join(subscales)}")
    reversed_ = entry.get("reversed", False)
    if not isinstance(reversed_, bool):
        raise QuestionnaireError(f"{where}: reversed must be true or false, got {reversed_!r}")
    return Item(
        entry["id"],
        _text(entry["text"], f"{where}.text"),
        low,
        high,
        tuple(sorted(labels.items())),
        tuple(member),
        reversed_,
    )


def parse_instrument(data: object, source: str = "instrument") -> Instrument:
    """An instrument as its JSON file has it, checked; QuestionnaireError names what is wrong and where."""
    top = _keys(
        data,
        ("about", "name", "title", "instruction", "scale", "scoring", "subscales", "items"),
        ("labels", "conditions"),
        source,
    )
    if not is_name(top["name"]):
        raise QuestionnaireError(f"{source}: name {top['name']!r} must be lower case letters, digits and _")
    scoring = _keys(top["scoring"], ("rule",), ("total",), f"{source}: scoring")
    rule = scoring["rule"]
    if rule not in RULES:
        raise QuestionnaireError(f"{source}: scoring.rule {rule!r} is not one of {', '.join(RULES)}")
    if "total" in scoring and rule != "weighted_sum":
        raise QuestionnaireError(f"{source}: scoring.total belongs to the weighted_sum rule only, not {rule}")
    if not (isinstance(top["subscales"], list) and top["subscales"]):
        raise QuestionnaireError(f"{source}: subscales must be a non-empty list, got {top['subscales']!r}")
    subscales = tuple(
        _subscale(entry, rule, f"{source}: subscale {number}") for number, entry in enumerate(top["subscales"], 1)
    )
    total = _subscale(scoring["total"], rule, f"{source}: scoring.total") if "total" in scoring else None
    ids = [s.id for s in subscales] + ([total.id] if total else [])
    if len(set(ids)) != len(ids):
        raise QuestionnaireError(f"{source}: the subscales' and total's ids repeat: {ids}")
    low, high = _scale(top["scale"], f"{source}: scale")
    default_labels = _labels(top["labels"], low, high, f"{source}: labels") if "labels" in top else {}
    if not (isinstance(top["items"], list) and top["items"]):
        raise QuestionnaireError(f"{source}: items must be a non-empty list, got {top['items']!r}")
    names = [s.id for s in subscales]
    items = tuple(
        _item(entry, low, high, default_labels, names, f"{source}: item {number}")
        for number, entry in enumerate(top["items"], 1)
    )
    repeated = sorted({item.id for item in items if [i.id for i in items].count(item.id) > 1})
    if repeated:
        raise QuestionnaireError(f"{source}: item id(s) {repeated} appear more than once")
    empty = [name for name in names if not any(name in item.subscales for item in items)]
    if empty:
        raise QuestionnaireError(f"{source}: subscale(s) {empty} have no item")
    conditions = top.get("conditions", [])
    if not (isinstance(conditions, list) and all(isinstance(c, str) and c for c in conditions)):
        raise QuestionnaireError(f"{source}: conditions must be a list of condition names, got {conditions!r}")
    return Instrument(
        name=top["name"],
        title=_text(top["title"], f"{source}: title"),
        about=_text(top["about"], f"{source}: about"),
        instruction=_text(top["instruction"], f"{source}: instruction"),
        items=items,
        subscales=subscales,
        rule=rule,
        total=total,
        conditions=tuple(conditions),
    )


def load_instrument(path: Path) -> Instrument:
    """The instrument in the JSON file `path`, checked; its name must be the file's."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as error:
        raise QuestionnaireError(f"cannot read the instrument {path}: {error.strerror}") from None
    except ValueError as error:
        raise QuestionnaireError(f"the instrument {path} is not JSON: {error}") from None
    instrument = parse_instrument(data, str(path))
    if instrument.name != path.stem:
        raise QuestionnaireError(f"{path}: name {instrument.name!r} must be the file's, {path.stem!r}")
    return instrument


@lru_cache(maxsize=None)
def standard_instrument(name: str) -> Instrument:
    """The bundled instrument `name` (one of STANDARD), read once."""
    if name not in STANDARD:
        raise QuestionnaireError(f"no standard questionnaire {name!r}; known: {', '.join(STANDARD)}")
    return load_instrument(FOLDER / f"{name}.json")


def single_item(name: str, data: object, source: str = "item") -> Instrument:
    """The lab's own single item `name` as the design declares it: {text, scale: [lowest, highest], labels: at
    least the two ends' (a list of two, or a mapping from answers)}. Scored as its answer, under its own name."""
    where = f"{source}: {name}"
    if not is_name(name) or name in STANDARD:
        raise QuestionnaireError(
            f"{where}: an item's name must be lower case letters, digits and _, and none of {', '.join(STANDARD)}"
        )
    entry = _keys(data, ("text", "scale", "labels"), (), where)
    text = _text(entry["text"], f"{where}.text")
    low, high = _scale(entry["scale"], f"{where}.scale")
    labels = _labels(entry["labels"], low, high, f"{where}.labels")
    if low not in labels or high not in labels:
        raise QuestionnaireError(f"{where}.labels must label both ends, {low} and {high}, got {entry['labels']!r}")
    item = Item(name, text, low, high, tuple(sorted(labels.items())), (name,))
    return Instrument(
        name=name,
        title=text,
        about="the lab's own item, declared in the study's design",
        instruction="",
        items=(item,),
        subscales=(Subscale(name, text),),
        rule="mean",
    )


def single_item_data(instrument: Instrument) -> dict[str, Any]:
    """A single item as `single_item` reads it (for a plan, which carries its own items)."""
    if len(instrument.items) != 1 or instrument.name in STANDARD:
        raise QuestionnaireError(f"{instrument.name} is not a single item of the lab's own")
    item = instrument.items[0]
    return {"text": item.text, "scale": [item.low, item.high], "labels": dict(item.labels)}
