"""Topics a template shares (`share(...)`): declarations, their checks, and the bridge routes
they make with the `zenoh` transport (pure: nothing runs)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from fleet.dataplane.echoes import Echoes
from fleet.errors import SpecError
from fleet.expand import expand_fleet
from fleet.spec import load_spec
from fleet.wire import protocol as p
from fleet.wire.topics import SharedRoute, bridge_routes
from tests.spec.test_bad_input import render_bad

TEMPLATE = """\
{{{{ share({share}) }}}}
launch:
- group:
  - push_ros_namespace: {{namespace: {{{{ robot.namespace }}}}}}
  - node: {{pkg: fleet_nodes, exec: battery, name: battery}}
"""
ANNOUNCE = '"/fleet/announcements", "std_msgs/msg/String", robot="both"'


def write_fleet(tmp_path: Path, share: str, transport: str = "zenoh", world: bool = False, **robots: str) -> Path:
    """A fleet of template `custom` (one share(...) call); robots: name -> agent."""
    templates = tmp_path / "my_templates"
    templates.mkdir(exist_ok=True)
    (templates / "custom.launch.yaml.j2").write_text(TEMPLATE.format(share=share))
    robots = robots or {"a1": "rack_a", "a2": "rack_a", "b1": "rack_b"}
    lines = "\n".join(f"  - {{name: {name}, agent: {agent}}}" for name, agent in robots.items())
    agents = ", ".join(f"{agent}: {{}}" for agent in sorted({*robots.values(), "sim"}))
    spec = tmp_path / "fleet.yaml"
    spec.write_text(
        f"fleet: demo\ntemplates: {templates}\nros: {{transport: {transport}}}\nagents: {{{agents}}}\n"
        + ("world: {agent: sim}\n" if world else "")
        + f"defaults: {{template: custom}}\nrobots:\n{lines}\n"
    )
    return spec


def routes_of(expansion) -> dict[str, tuple[list[str], list[str]]]:
    return {
        agent: ([r.name for r in routes.exports], [r.name for r in routes.imports])
        for agent, routes in expansion.bridge.items()
    }


def test_relative_names_resolve_in_each_robots_namespace_absolute_ones_are_fleet_wide(tmp_path):
    share = '"status", "std_msgs/msg/String", robot="publishes", reliability="best_effort", depth=5'
    expansion = expand_fleet(load_spec(write_fleet(tmp_path, share, transport="dds")))
    assert [robot.shared[0].name for robot in expansion.robots] == ["/a1/status", "/a2/status", "/b1/status"]
    topic = expansion.robots[0].shared[0]
    assert (topic.type, topic.reliable, topic.transient_local, topic.depth) == ("std_msgs/msg/String", False, False, 5)
    assert (topic.publishes, topic.subscribes) == (True, False)
    assert "share" not in expansion.robots[0].launch_text  # it declares, it prints nothing
    # With dds, DDS carries every topic across computers itself: no bridge, no routes.
    assert expansion.bridge == {}
    expansion = expand_fleet(load_spec(write_fleet(tmp_path, ANNOUNCE + ', durability="transient_local"')))
    assert {robot.shared[0].name for robot in expansion.robots} == {"/fleet/announcements"}
    assert expansion.robots[0].shared[0].transient_local


def test_a_share_under_a_boolean_launch_argument_follows_each_robots_value(tmp_path):
    """`{% if arg("enable_x", true) %}` around a share(...) of a node that the same argument
    starts: arg() gave the text "false", which Jinja's `if` held true, so a robot without the
    node still declared its topic (and status reported it without a publisher, forever)."""
    templates = tmp_path / "my_templates"
    templates.mkdir()
    (templates / "custom.launch.yaml.j2").write_text(
        "launch:\n- arg: {name: enable_x, default: {{ arg('enable_x', true) }}}\n"
        "{% if arg('enable_x', true) %}{{ share('x', 'std_msgs/msg/String', robot='publishes') }}{% endif %}\n"
        "{% if not arg('enable_x', true) %}{{ share('y', 'std_msgs/msg/String', robot='publishes') }}{% endif %}\n"
        "- group:\n  - push_ros_namespace: {namespace: {{ robot.namespace }}}\n"
        "  - node: {pkg: fleet_nodes, exec: battery, name: battery}\n"
    )
    spec = tmp_path / "fleet.yaml"
    spec.write_text(
        f"fleet: demo\ntemplates: {templates}\ndefaults: {{template: custom}}\n"
        "robots:\n- {name: a}\n- {name: b, launch_args: {enable_x: false}}\n"
    )
    expansion = expand_fleet(load_spec(spec))
    assert {robot.name: [topic.name for topic in robot.shared] for robot in expansion.robots} == {
        "a": ["/a/x"],
        "b": ["/b/y"],
    }
    assert 'default: "false"' in expansion.robots[1].launch_text


def test_a_topic_published_and_read_on_two_agents_goes_both_ways(tmp_path):
    expansion = expand_fleet(load_spec(write_fleet(tmp_path, ANNOUNCE)))
    both = (["/fleet/announcements"], ["/fleet/announcements"])
    assert routes_of(expansion) == {"rack_a": both, "rack_b": both}


def test_a_topic_goes_only_from_agents_that_publish_to_agents_that_subscribe():
    route = p.TopicRoute(name="/fleet/orders", type="std_msgs/msg/String")
    shared = [
        SharedRoute("dispatch", route, publishes=True, subscribes=False),
        SharedRoute("rack_a", route, publishes=False, subscribes=True),
        SharedRoute("rack_a", route, publishes=False, subscribes=True),
        SharedRoute("rack_b", route, publishes=False, subscribes=True),
        SharedRoute("rack_c", route, publishes=True, subscribes=False),  # publishes, reads nothing
    ]
    routes = bridge_routes(None, [], shared)
    assert routes["dispatch"] == p.BridgeRoutes(exports=[route])
    assert routes["rack_c"] == p.BridgeRoutes(exports=[route])
    assert routes["rack_a"] == routes["rack_b"] == p.BridgeRoutes(imports=[route])
    # Publishers and subscribers on one agent only: DDS on that computer suffices.
    assert bridge_routes(None, [], [SharedRoute("rack_a", route, True, True)] * 2) == {}
    # Published by robots, read by none: nowhere to go.
    assert (
        bridge_routes(None, [], [SharedRoute("rack_a", route, True, False), SharedRoute("rack_b", route, True, False)])
        == {}
    )


def test_shared_routes_come_beside_the_worlds():
    route = p.TopicRoute(name="/fleet/announcements", type="std_msgs/msg/String")
    robots = [("a1", "/a1", "rack_a"), ("w1", "/w1", "sim")]
    shared = [SharedRoute("rack_a", route, True, True), SharedRoute("sim", route, True, True)]
    routes = bridge_routes("sim", robots, shared)
    assert route in routes["sim"].exports and route in routes["sim"].imports
    assert "/a1/odom" in {r.name for r in routes["sim"].exports}
    assert route in routes["rack_a"].imports and "/clock" in {r.name for r in routes["rack_a"].imports}


def test_shared_routes_count_in_an_agents_bound(tmp_path, monkeypatch):
    monkeypatch.setattr(p, "MAX_ROUTES", 0)
    with pytest.raises(SpecError, match="would carry 1 topics one way"):
        expand_fleet(load_spec(write_fleet(tmp_path, ANNOUNCE)))


@pytest.mark.parametrize(
    "share, expected",
    [
        ('"~/goal", "std_msgs/msg/String"', "private (~)"),
        ('"pose/", "geometry_msgs/msg/Pose"', "empty token"),
        ('"2pose", "geometry_msgs/msg/Pose"', "must not start with a digit"),
        ('"pose", "geometry_msgs/Pose"', "write package/msg/Name"),
        ('"pose", "geometry_msgs/msg/Posse"', "package geometry_msgs has no message Posse"),
        ('"pose", "geometry_msgs/msg/Pose", reliability="sometimes"', "reliability is one of reliable, best_effort"),
        ('"pose", "geometry_msgs/msg/Pose", durability="latched"', "durability is one of volatile, transient_local"),
        ('"pose", "geometry_msgs/msg/Pose", depth=0', "depth is a whole number from 1 to 1000"),
        ('"pose", "geometry_msgs/msg/Pose", robot="reads"', "robot is one of publishes, subscribes, both"),
        ('"pose", "geometry_msgs/msg/Pose", qos="fast"', "unexpected keyword argument 'qos'"),
        ('"a/b/c/d/e/f/g/h/i", "std_msgs/msg/String"', "at most 8 tokens"),
    ],
)
def test_a_bad_declaration_is_one_line_at_its_template_line(tmp_path, capsys, share, expected):
    spec = write_fleet(tmp_path, share)
    line = render_bad(tmp_path, capsys, spec.read_text())
    assert f"{tmp_path / 'my_templates' / 'custom.launch.yaml.j2'}:1:" in line, line
    assert expected in line, line


def test_robots_must_share_a_topic_alike_and_not_the_worlds_own(tmp_path, capsys):
    templates = tmp_path / "my_templates"
    templates.mkdir()
    (templates / "custom.launch.yaml.j2").write_text(
        TEMPLATE.format(share='"/fleet/announcements", "std_msgs/msg/String", depth=(1 if robot.name == "r1" else 2)')
    )
    spec_text = f"""\
        fleet: demo
        templates: {templates}
        defaults: {{template: custom}}
        robots: [{{name: r1}}, {{name: r2}}]
    """
    line = render_bad(tmp_path, capsys, textwrap.dedent(spec_text))
    assert "shared topic /fleet/announcements: robots r1 and r2 declare it with QoS" in line, line
    (tmp_path / "w").mkdir()
    world = write_fleet(tmp_path / "w", '"odom", "nav_msgs/msg/Odometry"', world=True)
    # The call on the template's third line: the error names it (it named the file alone).
    template = tmp_path / "w" / "my_templates" / "custom.launch.yaml.j2"
    template.write_text("# shares\n\n" + template.read_text())
    line = render_bad(tmp_path / "w", capsys, world.read_text())
    assert "custom.launch.yaml.j2:3: robot a1 shares /a1/odom, which the world's topics already carry" in line, line


def test_a_template_declaring_a_topic_twice_combines_the_roles_and_refuses_another_type(tmp_path, capsys):
    share = (
        ANNOUNCE.replace("both", "publishes")
        + ') }}\n{{ share("/fleet/announcements", "std_msgs/msg/String", robot="subscribes"'
    )
    expansion = expand_fleet(load_spec(write_fleet(tmp_path, share)))
    (topic,) = expansion.robots[0].shared
    assert topic.publishes and topic.subscribes
    share = ANNOUNCE + ') }}\n{{ share("/fleet/announcements", "std_msgs/msg/Header"'
    line = render_bad(tmp_path, capsys, write_fleet(tmp_path, share).read_text())
    assert "declared twice: type std_msgs/msg/String and std_msgs/msg/Header" in line, line


def test_a_bridge_recognizes_its_own_echo_once():
    echoes = Echoes(seconds=60)
    echoes.brought_in(b"hello")
    echoes.brought_in(b"hello")
    assert not echoes.is_echo(b"other")
    assert echoes.is_echo(b"hello") and echoes.is_echo(b"hello")
    assert not echoes.is_echo(b"hello")  # a third, local one crosses
    stale = Echoes(seconds=0.0)
    stale.brought_in(b"late")
    assert not stale.is_echo(b"late")


def test_status_says_when_no_agent_has_seen_a_publisher_for_a_while():
    from fleet.plan.view import shared_topic_rows

    def states(**silent):
        return {
            agent: p.SharedTopicState(name="/t", publishers=0 if quiet is not None else 1, silent=quiet, age=age)
            for agent, (quiet, age) in silent.items()
        }

    (row,) = shared_topic_rows({"/t": states(rack_a=(12.4, 0.5), rack_b=(30.0, 0.5))})
    assert row["problem"] == "shared topic /t: no publisher on any agent for 12 s"
    assert row["publishers"] == {"rack_a": 0, "rack_b": 0}
    (row,) = shared_topic_rows({"/t": states(rack_a=(12.0, 0.5), rack_b=(None, 0.5))})
    assert row["problem"] == "" and row["publishers"] == {"rack_a": 0, "rack_b": 1}
    (row,) = shared_topic_rows({"/t": states(rack_a=(3.0, 0.5))})  # just started: not yet
    assert row["problem"] == ""
    (row,) = shared_topic_rows({"/t": states(rack_a=(12.0, 0.5), rack_b=(None, 60.0))})  # rack_b's watch is stale
    assert row["problem"].endswith("for 12 s") and row["publishers"] == {"rack_a": 0}


def test_the_worlds_topics_do_not_cross_for_a_real_robot():
    """A real robot (`simulated: false`) on another agent than the world's: its agent's bridge
    published phantom odom, scan and ground_truth (and /clock) beside its own driver's, and sent
    its every cmd_vel to the world's computer, which hosts no such robot."""
    from fleet.spec import parse_spec

    spec = (
        "fleet: demo\nros: {transport: zenoh}\nworld: {agent: sim}\nagents: {sim: {}, rack: {}, bench: {}}\n"
        "robots:\n- {name: s1, agent: rack}\n- {name: r1, agent: rack, simulated: false}\n"
        "- {name: r2, agent: bench, simulated: false}\n"
    )
    routes = routes_of(expand_fleet(parse_spec(spec, "f.yaml")))
    s1 = ["/s1/odom", "/s1/scan", "/s1/ground_truth"]
    assert routes == {
        "sim": (["/clock", *s1], ["/s1/cmd_vel", "/s1/battery"]),
        "rack": (["/s1/cmd_vel", "/s1/battery"], ["/clock", *s1]),
    }
