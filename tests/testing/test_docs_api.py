"""docs/testing.md's table of FleetHandle methods names each method's parameters as the code
does (a user copying `subscribe(..., msg_type=...)` from the docs got a TypeError)."""

from __future__ import annotations

import inspect
import re

from fleet.testing import FleetHandle
from tests.checkout import REPO

# `name(a, b=1)` in a row of the handle's table; calls with literal arguments
# (`topic(robot, "odom")`) are examples, not signatures, and are left out.
SIGNATURE = re.compile(r"`(\w+)\(((?:\w+(?:=[^,`()]+)?(?:, )?)*)\)`")


def documented_signatures() -> dict[str, list[str]]:
    text = (REPO / "docs" / "testing.md").read_text()
    table = text[text.index("## The handle") : text.index("### Waiting on sim time")]
    found: dict[str, list[str]] = {}
    for row in (line for line in table.splitlines() if line.startswith("| **")):
        for name, args in SIGNATURE.findall(row):
            if hasattr(FleetHandle, name):
                found[name] = [arg.split("=")[0] for arg in args.split(", ") if arg]
    return found


def test_the_docs_name_every_parameter_as_the_code_does():
    documented = documented_signatures()
    assert {"subscribe", "publish", "get_param", "wait_for", "logs"} <= set(documented)
    wrong = {}
    for name, params in documented.items():
        actual = [p for p in inspect.signature(getattr(FleetHandle, name)).parameters if p != "self"]
        if params != actual:
            wrong[name] = (params, actual)
    assert not wrong, "documented vs actual parameters: " + repr(wrong)


def test_the_failure_example_shows_a_domain_tests_reserve():
    text = (REPO / "docs" / "testing.md").read_text()
    stated = re.search(r"`ROS_DOMAIN_ID` in (\d+)\.\.(\d+)", text)
    example = re.search(r"^domain (\d+), router ", text, re.MULTILINE)
    assert stated and example
    first, last = map(int, stated.groups())
    shown = int(example.group(1))
    assert first <= shown <= last, f"the failure example shows domain {shown}, outside {first}..{last}"
