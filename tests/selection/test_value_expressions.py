"""Value expressions (``bagkit migrate``'s computed fields): parsed, evaluated on decoded
messages, never eval'd; bad text is a SelectionError naming the problem."""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np
import pytest

from bagkit.selection.errors import SelectionError, UnknownFieldError
from bagkit.selection.value_expressions import (
    evaluate_value,
    expression_paths,
    parse_value_expression,
)


@dataclass
class Cell:
    voltage: float


@dataclass
class Report:
    temperature: float = 21.5
    status: int = 3
    name: str = "pack"
    cells: list[Cell] = field(default_factory=lambda: [Cell(3.5), Cell(3.25)])
    ranges: np.ndarray = field(default_factory=lambda: np.array([1.0, 2.0, 4.0]))


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("temperature + 273.15", 21.5 + 273.15),
        ("-temperature * 2 - 1", -21.5 * 2 - 1),
        ("(status + 1) * (status - 1) % 5", ((3 + 1) * (3 - 1)) % 5),
        ("status / 2", 1.5),
        ("if(status >= 2, 'warn', 'ok')", "warn"),
        ("status == 3 and not name == 'x'", True),
        ("round(temperature / 3, 2)", round(21.5 / 3, 2)),
        ("max(cells[0].voltage, cells[1].voltage)", 3.5),
        ("len(cells)", 2),
        ("cells[1].voltage * 1000", 3250.0),
        ("str(status)", "3"),
        ("int(temperature)", 21),
    ],
)
def test_values(text: str, expected: object) -> None:
    assert evaluate_value(parse_value_expression(text), Report()) == expected


def test_arrays_go_element_by_element() -> None:
    report = Report()
    assert evaluate_value(parse_value_expression("ranges * 1000"), report).tolist() == [
        1000.0,
        2000.0,
        4000.0,
    ]
    assert evaluate_value(parse_value_expression("cells[*].voltage - 3"), report).tolist() == [
        0.5,
        0.25,
    ]


def test_paths_read() -> None:
    tree = parse_value_expression("if(status > 1, cells[*].voltage, temperature)")
    assert expression_paths(tree) == [("status",), ("cells", -1, "voltage"), ("temperature",)]


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("", "it is empty"),
        ("status +", "expected a value"),
        ("status $ 2", "unexpected '$'"),
        ("exec(status)", "unknown function 'exec'"),
        ("if(status, 1)", "if() takes 3 arguments, not 2"),
        ("status 2", "expected an operator or the end"),
        ("__class__", "unexpected '_'"),
    ],
)
def test_bad_text(text: str, problem: str) -> None:
    with pytest.raises(SelectionError, match=re.escape(problem)):
        parse_value_expression(text)


def test_bad_operands() -> None:
    with pytest.raises(SelectionError, match="division by zero"):
        evaluate_value(parse_value_expression("status / 0"), Report())
    with pytest.raises(SelectionError, match="name \\+ 1"):
        evaluate_value(parse_value_expression("name + 1"), Report())
    with pytest.raises(UnknownFieldError):
        evaluate_value(parse_value_expression("voltage * 2"), Report())
