"""Property: whatever a spec, a `--set` or a YAML document holds, loading and expanding it either
works or raises one FleetError whose line obeys the rule of docs/spec.md (one printable line of
at most 300 characters, `fleet: error: FILE:LINE:COL: problem`).  Nothing else: no traceback,
no hang.

CI runs a bounded number of examples from a fixed seed (profile `ci`); FLEET_HYPOTHESIS=deep runs
many more, from random seeds (docs/testing.md).
"""

from __future__ import annotations

import os
import re
import tempfile

# Hypothesis keeps a cache in its home directory (./.hypothesis by default): not in the checkout.
os.environ.setdefault("HYPOTHESIS_STORAGE_DIRECTORY", os.path.join(tempfile.gettempdir(), "fleet-hypothesis"))

import yaml
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from fleet.errors import MAX_LINE, FleetError
from fleet.expand import expand_fleet
from fleet.spec import parse_spec

settings.register_profile(
    "ci",
    max_examples=75,
    derandomize=True,
    database=None,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    "deep", max_examples=5000, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(os.environ.get("FLEET_HYPOTHESIS", "ci"))

FILE = "fuzz.yaml"
GOOD = """\
fleet: fuzz
world:
  obstacles: [{name: crate, type: box, position: [5, 5], size: [1, 1, 1]}]
robots:
  - name: robot1
    parameters:
      controller: {max_speed: 0.5, pid: {kp: 1.0}}
  - name: robot2
    pose: {x: 2.0}
"""


def check_outcome(run, located_in: str) -> None:
    """run() works, or raises a FleetError whose line obeys the one-line rule."""
    try:
        run()
        event("works")
    except FleetError as error:
        event(f"refused: {type(error).__name__}")
        line = error.line()
        assert line.startswith("fleet: error: "), line
        assert len(line) <= MAX_LINE, (len(line), line)
        assert line.isprintable(), repr(line)  # no newline, ESC, NUL...
        assert "\n" not in line and "\r" not in line
        assert error.exit_code == 2
        assert re.match(rf"fleet: error: {re.escape(located_in)}", line), line


def load_and_expand(text: str, sets: tuple[str, ...] = ()) -> None:
    expand_fleet(parse_spec(text, FILE), sets)


# -- random YAML documents ------------------------------------------------------------------------

# Pieces of YAML syntax, hostile values and characters: the documents they make are mostly
# invalid, in every way a parser can find.
FRAGMENTS = st.sampled_from(
    [
        "fleet: fuzz\n",
        "robots:\n",
        "  - name: r1\n",
        "  - name: world\n",
        "    pose: {x: ",
        "}\n",
        "[",
        "]",
        "{",
        "}",
        ": ",
        "- ",
        "  ",
        "\n",
        "&a ",
        "*a",
        "&b [*a, *a, *a]",
        "!!python/object:os.system ",
        "!tag ",
        "!!int ",
        "!!float ",
        "<<: *a\n",
        "? ",
        "---\n",
        "...\n",
        "'",
        '"',
        "\\",
        "#",
        "|\n",
        ">\n",
        ".nan",
        ".inf",
        "-.inf",
        "1e999",
        "9" * 40,
        "0x7fffffffffffffffff",
        "1:30",
        "2024-01-01",
        "~",
        "null",
        "yes",
        "\x00",
        "\x1b[31m",
        "\u2028",
        "\ufeff",
        "é",
        "\t",
        "parameters: {controller: {",
        "pid.kp: 1",
        "pid: {kp: 2}",
        "template: ../x",
        "template: world",
        "namespace: /a/b",
        "launch_args: {enable_safety: ",
    ]
)
DOCUMENTS = st.one_of(
    st.lists(FRAGMENTS, max_size=30).map("".join),
    st.text(max_size=200),
    st.lists(st.one_of(FRAGMENTS, st.text(max_size=10)), max_size=30).map("".join),
)


@given(DOCUMENTS)
def test_random_documents(text):
    check_outcome(lambda: load_and_expand(text), f"{FILE}:")


# -- random structures of the spec's shape --------------------------------------------------------

NAMES = st.one_of(
    st.sampled_from(["robot1", "robot2", "world", "r_1", "controller", "battery", "safety", "pid", "local"]),
    st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,8}", fullmatch=True),
    st.text(max_size=12),
)
NUMBERS = st.one_of(
    st.floats(min_value=-50, max_value=50),
    st.integers(min_value=-5, max_value=5),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=True, allow_infinity=True),
)
SCALARS = st.one_of(NUMBERS, st.booleans(), st.none(), st.text(max_size=20), NAMES)
VALUES = st.recursive(
    SCALARS,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(NAMES, inner, max_size=3)),
    max_leaves=12,
)
PARAMETERS = st.dictionaries(NAMES, st.dictionaries(NAMES, VALUES, max_size=4), max_size=3)
POSE = st.fixed_dictionaries({}, optional={"x": NUMBERS, "y": NUMBERS, "yaw": NUMBERS, "z": NUMBERS})
ROBOT = st.fixed_dictionaries(
    {"name": NAMES},
    optional={
        "pose": st.one_of(POSE, SCALARS),
        "parameters": st.one_of(PARAMETERS, SCALARS),
        "launch_args": st.dictionaries(NAMES, SCALARS, max_size=3),
        "template": st.one_of(NAMES, st.sampled_from(["diff_drive", "world", "../templates/diff_drive", "/etc/x"])),
        "namespace": st.one_of(NAMES.map(lambda name: f"/{name}"), st.text(max_size=300)),
        "model": st.fixed_dictionaries({}, optional={"type": NAMES, "radius": NUMBERS}),
        "lidar": st.fixed_dictionaries({}, optional={"range_min": NUMBERS, "range_max": NUMBERS, "beams": NUMBERS}),
        "simulated": st.booleans(),
        "agent": NAMES,
    },
)
OBSTACLE = st.fixed_dictionaries(
    {"name": NAMES, "type": st.sampled_from(["box", "wall", "cylinder", "cone"])},
    optional={
        "position": st.lists(NUMBERS, max_size=3),
        "size": st.lists(NUMBERS, max_size=4),
        "radius": NUMBERS,
    },
)
# hypothesis types the required part of a dictionary strategy from its first entries: ignore.
SPECS = st.fixed_dictionaries(
    {"fleet": NAMES, "robots": st.lists(ROBOT, max_size=4, unique_by=lambda robot: str(robot["name"]))},  # type: ignore[dict-item]
    optional={
        "world": st.fixed_dictionaries({}, optional={"obstacles": st.lists(OBSTACLE, max_size=3)}),
        "defaults": st.fixed_dictionaries(
            {}, optional={"parameters": PARAMETERS, "launch_args": st.dictionaries(NAMES, SCALARS, max_size=2)}
        ),
        "agents": st.dictionaries(NAMES, st.just({}), max_size=2),
        "ros": st.fixed_dictionaries({}, optional={"domain_id": NUMBERS}),
    },
)


@given(SPECS)
def test_random_specs(spec):
    text = yaml.safe_dump(spec, allow_unicode=True)
    check_outcome(lambda: load_and_expand(text), f"{FILE}:")


# -- random --set arguments -------------------------------------------------------------------------

KEYS = st.one_of(
    st.sampled_from(
        ["robot1.controller.max_speed", "robot2.controller.pid.kp", "robot1.controller.pid", "robot1.battery.capacity"]
    ),
    st.lists(NAMES, min_size=1, max_size=5).map(".".join),
    st.text(max_size=30),
)
SET_VALUES = st.one_of(
    st.sampled_from(["0.8", "1", "true", "[1, 2]", "[[1]]", "{a: 1}", ".nan", "9" * 30, "&a [*a]", "!!set {}", ""]),
    st.text(max_size=30),
)


PLAUSIBLE_SETS = st.tuples(
    st.sampled_from(["robot1.controller.max_speed", "robot2.controller.pid.kp", "robot1.battery.capacity"]),
    st.sampled_from(["0.8", "2", "1.5e1", "-0.0"]),
).map("=".join)


@given(
    st.lists(PLAUSIBLE_SETS | st.tuples(KEYS, SET_VALUES).map("=".join) | st.text(max_size=30), min_size=1, max_size=3)
)
def test_random_set_arguments(sets):
    spec = parse_spec(GOOD, FILE)
    check_outcome(lambda: expand_fleet(spec, sets), "--set ")


# -- the loader reads what YAML means ---------------------------------------------------------------

PLAIN_DATA = st.recursive(
    st.one_of(
        st.integers(min_value=-(2**63), max_value=2**63 - 1),
        st.floats(allow_nan=False, allow_infinity=False),
        st.booleans(),
        st.none(),
        st.text(max_size=20),
    ),
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=4)),
    max_leaves=20,
)


@given(PLAIN_DATA, st.booleans())
def test_loader_reads_what_pyyaml_reads(data, shared):
    """Within its limits, fleet's loader gives what yaml.safe_load gives (anchors and aliases too)."""
    from fleet.spec.yaml_source import load_yaml

    document = {"a": data, "b": data} if shared else data  # safe_dump writes a shared value as &id001/*id001
    text = yaml.safe_dump(document, allow_unicode=True)
    loaded, places = load_yaml(text, FILE)
    assert loaded == yaml.safe_load(text)
    assert places.locate(()).line is not None
