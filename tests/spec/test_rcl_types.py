"""fleet types parameter values exactly as rcl does: checked against what a real rcl made of each
recorded scalar and list (tests/expand/data/rcl_scalar_types.json)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import yaml

from fleet.spec.rcl_types import rcl_scalar, sequence_problem

RECORDED = json.loads((Path(__file__).parents[1] / "expand" / "data" / "rcl_scalar_types.json").read_text())
TYPES = {"bool": bool, "integer": int, "double": float, "string": str}


def _written(text: str) -> tuple[str, bool]:
    """The scalar's text and whether it was quoted, as the YAML parser hands them over."""
    root = yaml.compose(f"v: {text}")
    assert root is not None
    node = root.value[0][1]
    return node.value, node.style in ("'", '"')


@pytest.mark.parametrize("case", RECORDED["scalars"], ids=[case["yaml"] for case in RECORDED["scalars"]])
def test_scalars_typed_as_rcl_types_them(case):
    value = rcl_scalar(*_written(case["yaml"]))
    assert type(value) is TYPES[case["type"]], (case, value)
    if isinstance(case["value"], str) and case["type"] == "double":  # inf / nan, recorded as repr
        assert isinstance(value, float)
        assert repr(value) == case["value"] or (case["value"] == "nan" and math.isnan(value))
    else:
        assert value == case["value"]


@pytest.mark.parametrize("case", RECORDED["sequences"], ids=[case["yaml"] for case in RECORDED["sequences"]])
def test_lists_refused_where_rcl_refuses_them(case):
    root = yaml.compose(f"v: {case['yaml']}")
    assert root is not None
    items = root.value[0][1].value
    values = [rcl_scalar(item.value, item.style in ("'", '"')) for item in items]
    if "refused" in case:
        assert sequence_problem(values) is not None
    else:
        assert sequence_problem(values) is None and values == case["value"]


def test_edges_of_the_c_conversions():
    assert rcl_scalar("-0x10") == -16 and rcl_scalar("0") == 0 and rcl_scalar("-07") == -7
    assert rcl_scalar(str(2**63 - 1)) == 2**63 - 1 and rcl_scalar(str(2**63)) == float(2**63)  # strtoll overflow
    assert rcl_scalar("1e-310") == "1e-310"  # subnormal: ERANGE
    assert rcl_scalar("0.0") == 0.0 and rcl_scalar("0e5") == 0.0  # a true zero is no underflow
    assert rcl_scalar("+.inf") == math.inf and math.isnan(float(rcl_scalar("NAN")))
    assert rcl_scalar("true", quoted=True) == "true"


@pytest.mark.parametrize(
    "value, text",
    [
        (True, "true"),
        (False, "false"),
        (0.1, "0.1"),
        (1e-05, "1e-05"),
        (2.0, "2.0"),
        (-3, "-3"),
        ("hello", "hello"),
        ("base_link", "base_link"),
        ("/robot1/odom", "/robot1/odom"),
        ("two words", "two words"),
        ("true", "'true'"),
        ("no", "'no'"),
        ("0.5", "'0.5'"),
        ("1e-1", "'1e-1'"),
        ("", "''"),
        (" x", "' x'"),
        ("a: b", "'a: b'"),
        ("it's", "'it''s'"),
        ("-", "'-'"),
        ("line\nbreak", '"line\\nbreak"'),
        ([1.0, 2.5], "[1.0, 2.5]"),
        ([True, False], "[true, false]"),
        (["front", "a, b", "yes"], "[front, 'a, b', 'yes']"),
        (math.inf, ".inf"),
    ],
)
def test_values_are_shown_as_ros_yaml_and_read_back_the_same(value, text):
    from fleet.spec.params import command_line_value
    from fleet.spec.rcl_types import value_text

    assert value_text(value) == text
    if not (isinstance(value, float) and math.isinf(value)):  # a value fleet refuses to be given
        again = command_line_value(text)
        assert again == value and type(again) is type(value), (text, again)
        if isinstance(value, list):
            assert [type(item) for item in again] == [type(item) for item in value]
