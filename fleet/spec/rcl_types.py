"""How rcl types a parameter value written in YAML (pure): the rule of every parameter fleet reads.

rcl's parameter-file parser (rcl_yaml_param_parser, parse.c get_value) does not use YAML's
schemas.  For a plain (unquoted, untagged) scalar it tries, in order:
- bool: exactly one of y Y yes Yes YES true True TRUE on On ON (true) or the matching false words
  n N no No NO false False FALSE off Off OFF;
- int64: C strtoll(text, base 0) consuming the whole text without overflow (so `010` is 8,
  `0x1f` is 31, `1_000` is not an integer);
- double: C strtod consuming the whole text without range error (so `1e-3`, `5.`, `.5`, `inf`,
  `nan`, `Infinity`, hex floats, `09` (9.0) are doubles; `1.5e400` is not), plus YAML's `.inf`,
  `+.inf`, `-.inf` and `.nan` spellings;
- else a string (`~`, `null`, dates, `12:30` stay strings).
Quoted scalars and `!!str` are strings.  A sequence must hold one type (no ints among doubles).
tests/expand/data/rcl_scalar_types.json records what a real rcl made of each of these.

value_text writes a value the other way round: as ROS YAML shows it, and rcl reads it back.
"""

from __future__ import annotations

import json
import math
import re
import sys

from fleet.rules import ros_type

RclValue = bool | int | float | str

_TRUE = frozenset({"y", "Y", "yes", "Yes", "YES", "true", "True", "TRUE", "on", "On", "ON"})
_FALSE = frozenset({"n", "N", "no", "No", "NO", "false", "False", "FALSE", "off", "Off", "OFF"})
_YAML_SPECIALS = {
    **{f"{sign}.{word}": float(f"{sign}inf") for sign in ("", "+", "-") for word in ("inf", "Inf", "INF")},
    **{f".{word}": math.nan for word in ("nan", "NaN", "NAN")},
}
INT64_MIN, INT64_MAX = -(2**63), 2**63 - 1

# strtoll with base 0: optional sign, then 0x/0X and hex digits, or 0 and octal digits, or decimal.
_STRTOLL = re.compile(r"[+-]?(?:0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)")
# strtod: decimal (with optional exponent), hexadecimal (with optional binary exponent), inf, nan.
_DECIMAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_HEX_FLOAT = re.compile(r"([+-]?)0[xX]((?:[0-9a-fA-F]+\.?[0-9a-fA-F]*|\.[0-9a-fA-F]+)(?:[pP][+-]?[0-9]+)?)")
_INF_NAN = re.compile(r"[+-]?(?:inf|infinity|nan)", re.IGNORECASE)
_NONZERO_DIGIT = re.compile(r"[1-9a-fA-F]")
# The common spelling of a double (0.5, -12.25): read at once, without the tries above.  Short
# enough that it can neither overflow nor underflow.
_PLAIN_DOUBLE = re.compile(r"-?[0-9]{1,150}\.[0-9]{1,150}")


def rcl_scalar(text: str, quoted: bool = False) -> RclValue:
    """The value rcl gives a scalar written as `text` (quoted: in '...' or "...", or `!!str`)."""
    if quoted:
        return text
    if _PLAIN_DOUBLE.fullmatch(text):
        return float(text)
    if text in _TRUE:
        return True
    if text in _FALSE:
        return False
    if _STRTOLL.fullmatch(text):
        value = _strtoll(text)
        if INT64_MIN <= value <= INT64_MAX:
            return value
    number = _strtod(text)
    return text if number is None else number


def is_integer_text(text: str) -> bool:
    """True when strtoll reads all of `text` (whether or not the integer fits in 64 bits)."""
    return _STRTOLL.fullmatch(text) is not None


def is_double_out_of_range(text: str) -> bool:
    """Whether `text` is written as a number a double cannot hold (1.0e+400, 1e-400): strtod
    refuses it (ERANGE), so rcl reads it as the string."""
    return bool(_DECIMAL.fullmatch(text) or _HEX_FLOAT.fullmatch(text)) and _strtod(text) is None


def _strtoll(text: str) -> int:
    sign = -1 if text[0] == "-" else 1
    digits = text.lstrip("+-")
    if digits[:2] in ("0x", "0X"):
        return sign * int(digits[2:], 16)
    if len(digits) > 1 and digits[0] == "0":
        return sign * int(digits[1:], 8)
    if len(digits) > 20:  # beyond int64 however it ends, and beyond what Python's int() may read
        return sign * (INT64_MAX + 1) * 2
    return sign * int(digits)


def _strtod(text: str) -> float | None:
    """strtod's value when it would consume all of `text` without a range error, else None."""
    if text in _YAML_SPECIALS:
        return _YAML_SPECIALS[text]
    if _INF_NAN.fullmatch(text):
        return float(text)
    hexadecimal = _HEX_FLOAT.fullmatch(text)
    if hexadecimal:
        sign, body = hexadecimal.groups()
        mantissa = body.split("p")[0].split("P")[0]
        body = body if "p" in body.lower() else body + "p0"
        try:
            value = float.fromhex(sign + "0x" + body)
        except OverflowError:
            return None
    elif _DECIMAL.fullmatch(text):
        mantissa = text.lower().split("e")[0]
        value = float(text)
        if math.isinf(value):
            return None  # overflow: strtod sets ERANGE
    else:
        return None
    if value == 0.0 and _NONZERO_DIGIT.search(mantissa.lstrip("+-").replace("0x", "").replace("0X", "")):
        return None  # underflow to zero: ERANGE
    if value != 0.0 and abs(value) < sys.float_info.min:
        return None  # a subnormal result: glibc's strtod reports ERANGE too
    return value


def sequence_problem(values: list[RclValue]) -> str | None:
    """Why rcl refuses a list of parameter values, or None (one type throughout, not empty)."""
    if not values:
        return "an empty list has no type for rcl (the parameter would not be set)"
    kinds = {ros_type(value) for value in values}
    if len(kinds) > 1:
        return f"a list must hold one type for rcl, got {' and '.join(sorted(kinds))} values"
    return None


# A string shown as it is: words of ordinary characters between single spaces, the lone "-" (a
# YAML list item) excepted.  Anything else YAML could read otherwise (`a: b`, `[x]`, `#`, edge
# blanks), so it is quoted.
_PLAIN_STRING = re.compile(r"(?!-(?: |$))[\w/.~+()=<>$^-]+(?: [\w/.~+()=<>$^-]+)*")


def value_text(value: object) -> str:
    """A parameter value written as ROS YAML writes it (`ros2 param dump`), the one way fleet shows
    values to people: true/false, 0.5, [1.0, 2.0], a string as it is unless rcl would read it
    as something else (`'true'`, `'0.5'`, `''`).  Written on the command line (`fleet param set`,
    `--set`), the text gives back the same value."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and not math.isfinite(value):
        return ".nan" if math.isnan(value) else ".inf" if value > 0 else "-.inf"
    if isinstance(value, list):
        return "[" + ", ".join(value_text(item) for item in value) + "]"
    if isinstance(value, str) and not (_PLAIN_STRING.fullmatch(value) and rcl_scalar(value) == value):
        if not value.isprintable():  # YAML's double quotes, as JSON's, escape newlines and the like
            return json.dumps(value, ensure_ascii=False)
        return "'" + value.replace("'", "''") + "'"
    return str(value)
