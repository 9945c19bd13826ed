"""The agent's check of a bundle's parameter files (fleet.spec.load.check_parameter_file):
what rcl reads passes, including every file fleet writes; what would stop a node at start is
refused at its line."""

from __future__ import annotations

import pytest

from fleet.errors import SpecError
from fleet.expand import expand_fleet
from fleet.rules import PARAMS_SUFFIX
from fleet.spec import load_spec
from fleet.spec.load import check_parameter_file
from tests.checkout import FLEETS

FILE = "robot1/robot1.params.yaml"


@pytest.mark.parametrize("spec", sorted(FLEETS.glob("*.yaml")), ids=lambda path: path.stem)
def test_every_parameter_file_fleet_writes_passes(spec):
    expansion = expand_fleet(load_spec(spec))
    checked = 0
    for bundle in expansion.bundles:
        for name, text in bundle.files.items():
            if name.endswith(PARAMS_SUFFIX):
                check_parameter_file(text, f"{bundle.name}/{name}")
                checked += 1
    assert checked


@pytest.mark.parametrize(
    "text",
    [
        "",
        "/robot1/controller:\n  ros__parameters:\n    max_speed: 0.5\n    waypoints: [1.0, 2.0]\n",
        "robot1:\n  controller:\n    ros__parameters:\n      pid: {kp: 1.0}\n",  # a name over two levels
        "/**:\n  ros__parameters:\n    use_sim_time: true\n",
        "/robot1/controller:\n  ros__parameters: {}\n",
    ],
)
def test_what_rcl_reads_passes(text):
    check_parameter_file(text, FILE)


@pytest.mark.parametrize(
    ("text", "place", "words"),
    [
        ("/robot1/c:\n  ros__parameters: {a: [1,\n", ":3:", "YAML syntax error"),
        ("- a\n", ":1", "maps node names to their parameters"),
        ("/robot1/c:\n  max_speed: 0.5\n", ":2:3", "expected the node's {ros__parameters: {...}}"),
        ("/robot1/c: 3\n", ":1:1", "expected the node's"),
        ("/robot1/c:\n  ros__parameters: 3\n", ":2:", "ros__parameters must map parameter names to values"),
        ("/robot1/c:\n  ros__parameters:\n    a: [1, 2.5]\n", ":3:", "mixed-type list"),
        ("/robot1/c:\n  ros__parameters:\n    a:\n", ":3:", "rcl refuses an empty parameter value"),
        ("/robot1/c:\n  ros__parameters:\n    a: 1\n    a.b: 2\n", ":", "both a parameter and the namespace"),
    ],
)
def test_what_would_stop_a_node_is_refused_at_its_place(text, place, words):
    with pytest.raises(SpecError) as refused:
        check_parameter_file(text, FILE)
    assert str(refused.value.location).startswith(FILE + place), refused.value.location
    assert words in refused.value.message
