"""Numbers as a user types them on a command line: a float or a small arithmetic expression with pi, one or many.
Pure logic."""

from __future__ import annotations

import ast
import math
import operator

from sim.errors import SimError

__all__ = ["CliValueError", "parse_number", "parse_numbers"]


class CliValueError(SimError, ValueError):
    """A value that is not a number; the message quotes it."""


_OPERATORS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv}


def parse_number(text: str) -> float:
    """A float, or a small arithmetic expression of numbers and `pi` (e.g. pi/4, -2*pi/5)."""

    def evaluate(node: ast.AST) -> float:
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
            return float(node.value)
        if isinstance(node, ast.Name) and node.id == "pi":
            return math.pi
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            value = evaluate(node.operand)
            return -value if isinstance(node.op, ast.USub) else value
        if isinstance(node, ast.BinOp) and type(node.op) in _OPERATORS:
            return _OPERATORS[type(node.op)](evaluate(node.left), evaluate(node.right))
        raise ValueError(text)

    try:
        value = evaluate(ast.parse(text.strip(), mode="eval").body)
    except (SyntaxError, ValueError, ZeroDivisionError):
        raise CliValueError(f"not a number: {text!r} (use e.g. 0.5, -2.45, pi/4)") from None
    if not math.isfinite(value):
        raise CliValueError(f"not a finite number: {text!r}")
    return value


def parse_numbers(tokens: list[str] | None, what: str) -> list[float] | None:
    """Numbers given space- and/or comma-separated: `--goal 0.5 0.375 0.75` or `--goal=0.5,0.375,0.75`."""
    if tokens is None:
        return None
    parts = [part for token in tokens for part in token.replace(",", " ").split()]
    if not parts:
        raise CliValueError(f"{what}: no numbers given")
    return [parse_number(part) for part in parts]
