"""sim.cli_values: numbers as users type them (floats, pi expressions, lists split by spaces or commas)."""

from __future__ import annotations

import math

import pytest

from sim.cli_values import CliValueError, parse_number, parse_numbers


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("0.5", 0.5),
        ("-2.45", -2.45),
        ("pi/4", math.pi / 4),
        ("-2*pi/5", -2 * math.pi / 5),
        (" +3 ", 3.0),
        ("1e-3", 1e-3),
        ("pi - 1", math.pi - 1),
    ],
)
def test_numbers_and_pi_expressions(text: str, value: float) -> None:
    assert parse_number(text) == pytest.approx(value)


@pytest.mark.parametrize("text", ["", "x", "pi**2", "__import__('os')", "1/0", "nan", "1e400", "[1]", "2 pi"])
def test_anything_else_is_refused_by_name(text: str) -> None:
    with pytest.raises(CliValueError, match="number"):
        parse_number(text)


def test_lists_split_on_spaces_and_commas() -> None:
    assert parse_numbers(["0.5", "0.375,0.75"], "--goal") == [0.5, 0.375, 0.75]
    assert parse_numbers(["-2,1"], "--waypoints") == [-2.0, 1.0]
    assert parse_numbers(None, "--goal") is None
    with pytest.raises(CliValueError, match="--goal: no numbers"):
        parse_numbers([" , "], "--goal")
