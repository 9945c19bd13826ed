"""`fleet render` refuses what the world or the agents would refuse later, by asking their own
rules: the world's spawn check (fleet.world.geometry), its description checks, and the protocol's
limits on what an agent accepts.  And it does so in time linear in robots."""

from __future__ import annotations

import pytest

from fleet.errors import FleetError, SpecError
from fleet.expand import expand_fleet
from fleet.spec import parse_spec
from fleet.wire import limits, protocol
from fleet.world import geometry
from fleet.world.description import ModelSpec, ObstacleSpec, Pose2D, RobotSpec, WorldSpec


def spec_text(robots: list[str], world: str = "world: {}\n", agents: str = "") -> str:
    return "fleet: demo\n" + world + agents + "robots:\n" + "".join(f"  - {robot}\n" for robot in robots)


POSES = [(0.0, 0.0, 0.0), (0.41, 0.0, 0.0), (0.43, 0.0, 0.0), (1.0, 1.0, 0.5), (1.2, 1.3, 0.0), (2.05, 0.0, 0.0)]


@pytest.mark.parametrize("second", POSES[1:])
@pytest.mark.parametrize("model", ["light", "husky"])
def test_render_and_the_physics_world_refuse_the_same_spawn_poses(second, model):
    """One rule: what PhysicsWorld.add_robot refuses, render refuses, and only that."""
    from fleet.world.physics import PhysicsWorld, SpawnError

    crate = ObstacleSpec("crate", "box", 2.6, 0.0, 0.0, size=(1.0, 1.0, 1.0), height=1.0)
    world = PhysicsWorld(240.0)
    try:
        world.add_obstacle(crate)
        world.add_robot("a", ModelSpec(type=model), Pose2D(*POSES[0]))
        try:
            world.add_robot("b", ModelSpec(type=model), Pose2D(*second))
            physics_refuses = False
        except SpawnError:
            physics_refuses = True
    finally:
        world.close()
    text = spec_text(
        [
            f"{{name: a, model: {{type: {model}}}}}",
            f"{{name: b, model: {{type: {model}}}, pose: {{x: {second[0]}, y: {second[1]}, yaw: {second[2]}}}}}",
        ],
        world="world:\n  obstacles: [{name: crate, type: box, position: [2.6, 0.0], size: [1, 1, 1]}]\n",
    )
    try:
        expand_fleet(parse_spec(text, "f.yaml"))
        render_refuses = False
    except SpecError as error:
        assert "the world would not spawn it" in str(error)
        render_refuses = True
    assert render_refuses == physics_refuses


def _world(robots: tuple[RobotSpec, ...]) -> WorldSpec:
    return WorldSpec(fleet="grid", physics_rate=240.0, real_time=True, clock_rate=100.0, obstacles=(), robots=robots)


def test_spawn_check_compares_each_robot_with_its_neighbours_only(monkeypatch):
    """Linear, not quadratic: 3,000 robots in a grid cost a few overlap tests each."""
    calls = []
    real = geometry.overlaps

    def counted(*args):
        calls.append(1)
        return real(*args)

    monkeypatch.setattr(geometry, "overlaps", counted)
    robots = tuple(RobotSpec(f"r{i}", f"/r{i}", pose=Pose2D((i % 60) * 0.5, (i // 60) * 0.5, 0.0)) for i in range(3000))
    assert geometry.spawn_problem(_world(robots)) is None
    assert len(calls) < 10 * len(robots)
    crowded = (*robots, RobotSpec("late", "/late", pose=Pose2D(10.1, 10.0, 0.0)))
    problem = geometry.spawn_problem(_world(crowded))
    assert problem is not None
    index, why = problem
    assert index == 3000 and "of robot 'late' overlaps robot 'r1220' at (10.00, 10.00)" in why


def test_robots_that_are_not_simulated_are_not_placed():
    text = spec_text(["{name: a}", "{name: b, simulated: false}"])
    expansion = expand_fleet(parse_spec(text, "f.yaml"))
    assert [bundle.name for bundle in expansion.bundles] == ["a", "b", "world"]
    # The agent reports which robot is real: fleet status does not judge it by the world.
    options = {bundle.name: dict(bundle.options) for bundle in expansion.bundles}
    assert options["b"]["simulated"] is False and "simulated" not in options["a"]
    assert protocol.BundleMessage.from_bundle(expansion.bundles[1]).simulated is False
    assert protocol.BundleMessage.from_bundle(expansion.bundles[0]).simulated is True


def test_a_world_description_an_agent_would_refuse_is_refused():
    robots = [f"{{name: r{i}, agent: a{i % 4}, pose: {{x: {i % 100}, y: {i // 100}}}}}" for i in range(3500)]
    # Agents that accept that many robots (agents.*.max_robots), so the world's size is what fails.
    agents = (
        "agents: {a0: {max_robots: 5000}, a1: {max_robots: 5000}, a2: {max_robots: 5000}, a3: {max_robots: 5000}}\n"
    )
    agents += "defaults: {agent: a0}\n"
    with pytest.raises(SpecError, match=r"f.yaml:2:\d+: an agent would refuse the world's files: file 'world.yaml'"):
        expand_fleet(parse_spec(spec_text(robots, agents=agents), "f.yaml"))


def test_more_robots_on_an_agent_than_it_accepts_are_refused():
    robots = [f"{{name: r{i}, pose: {{x: {i}}}}}" for i in range(limits.MAX_BUNDLES)]  # and the world: one more
    agents = f"agents: {{local: {{max_robots: {limits.MAX_BUNDLES}}}}}\n"  # the spec allows it; an agent does not
    with pytest.raises(SpecError, match=f"agent local would run {limits.MAX_BUNDLES + 1} units; an agent runs at most"):
        expand_fleet(parse_spec(spec_text(robots, agents=agents), "f.yaml"))
    # With the default limit, the spec's own check comes first.
    with pytest.raises(SpecError, match="agent 'local' holds at most 300 robots"):
        expand_fleet(parse_spec(spec_text(robots), "f.yaml"))
    expand_fleet(parse_spec(spec_text(robots[1:], agents=agents), "f.yaml"))


def test_a_deploy_message_an_agent_would_refuse_is_refused():
    note = "x" * 100_000  # a long parameter makes each robot's files big: 90 robots, 9 MB
    robots = [f'{{name: r0, parameters: {{controller: {{note: &note "{note}"}}}}}}']
    robots += [f"{{name: r{i}, parameters: {{controller: {{note: *note}}}}}}" for i in range(1, 90)]
    with pytest.raises(
        SpecError, match=r"agent local's 90 units make a deploy message of up to 9\.\d MiB; an agent accepts 8 MiB"
    ):
        expand_fleet(parse_spec(spec_text(robots, world=""), "f.yaml"))


def test_the_size_bound_is_above_the_real_message():
    """apply_size_bound never says less than the ApplyRequest really is."""
    robots = ['{name: a, parameters: {controller: {note: "é\\u2028\\n\\"x"}}}', "{name: b, pose: {x: 2}}"]
    robots.append("{name: " + "r" * 63 + ", pose: {x: 4}, agent: " + "h" * 63 + "}")  # the longest names
    agents = "agents: {local: {}, " + "h" * 63 + ": {}}\n"
    expansion = expand_fleet(parse_spec("fleet: " + "f" * 63 + "\n" + spec_text(robots, agents=agents)[12:], "f.yaml"))
    request = protocol.ApplyRequest(
        fleet="f" * 63,
        agent="h" * 63,
        generation=1,
        domain_id=0,
        bundles=[protocol.BundleMessage.from_bundle(bundle) for bundle in expansion.bundles],
    )
    assert len(protocol.encode(request)) <= limits.apply_size_bound(bundle.json_size for bundle in expansion.bundles)


ZENOH = "fleet: demo\nros: {transport: zenoh}\nworld: {agent: sim}\n"


def test_the_size_bound_counts_the_zenoh_bridge_routes():
    """With the `zenoh` transport a deploy message also carries the agent's bridge routes; the
    bound render checks is above each real message, routes included."""
    from fleet.plan import requests_for

    agents = "agents: {sim: {}, rack: {}}\n"
    robots = "robots:\n" + "".join(f"  - {{name: r{i}, agent: rack, pose: {{x: {i}}}}}\n" for i in range(40))
    expansion = expand_fleet(parse_spec(ZENOH + agents + robots, "f.yaml"))
    assert len(expansion.bridge["sim"].exports) == 1 + 3 * 40  # /clock and each robot's odom, scan, ground_truth
    for request in requests_for(expansion, generation=1, serving=set()):
        assert request.bridge.exports or request.bridge.imports
        group = [bundle for bundle in expansion.bundles if bundle.agent == request.agent]
        without_routes = limits.apply_size_bound(bundle.json_size for bundle in group)
        size = len(protocol.encode(request))
        assert size <= without_routes + len(expansion.bridge[request.agent].model_dump_json())
        if request.agent == "sim":  # the world alone: its routes are most of the message
            assert size > without_routes


def test_more_bridge_routes_than_an_agent_carries_are_refused():
    """The world's agent bridges three topics for every robot elsewhere: past MAX_ROUTES the
    agent would refuse the deploy message, so render refuses the spec, at ros.transport."""
    per_rack = 900  # 1,800 robots elsewhere: 5,401 routes out of the world's agent
    agents = "agents: {sim: {}, " + ", ".join(f"rack{k}: {{max_robots: {per_rack}}}" for k in (1, 2)) + "}\n"
    robots = "robots:\n" + "".join(
        f"  - {{name: r{i}, agent: rack{1 + i // per_rack}, pose: {{x: {i}}}}}\n" for i in range(2 * per_rack)
    )
    with pytest.raises(SpecError, match=r"f.yaml:2:7: agent sim's Zenoh bridge would carry 5401 topics one way"):
        expand_fleet(parse_spec(ZENOH + agents + robots, "f.yaml"))
    dds = (ZENOH + agents + robots).replace("transport: zenoh", "transport: dds")
    expand_fleet(parse_spec(dds, "f.yaml"))  # the same fleet bridges nothing with dds


def _render_template(tmp_path, template: str, robots: str = "[{name: robot1}, {name: robot2}]"):
    templates = tmp_path / "templates"
    templates.mkdir(exist_ok=True)
    (templates / "t.launch.yaml.j2").write_text(template)
    spec = f"fleet: demo\ntemplates: {templates}\ndefaults: {{template: t}}\nrobots: {robots}\n"
    return expand_fleet(parse_spec(spec, str(tmp_path / "f.yaml")))


NODE = "  - node: {{pkg: demo, exec: talker, name: {name}{extra}}}\n"
GROUP = "launch:\n- group:\n  - push_ros_namespace: {namespace: {{ robot.namespace }}}\n"


@pytest.mark.parametrize(
    ("nodes", "place", "problem"),
    [
        (NODE.format(name="shadow-ctl", extra=""), "4:5", "node 'shadow-ctl' is not a valid ROS name"),
        (NODE.format(name="c", extra=", args: --log $(var loglevel)"), "4:5", "'loglevel' is not defined"),
        (NODE.format(name="main_ctl", extra="") * 2, "5:5", "two nodes are named /robot1/main_ctl"),
        (
            NODE.format(name="c", extra=", remap: [{from: odom, to: '/{{ robot.name }}/odom'}]"),
            "4:5",
            "invalid remap 'odom' -> '/\"robot1\"/odom'",
        ),
        (NODE.format(name="c", extra=", remap: [{from: cmd-vel, to: x}]"), "4:5", "from 'cmd-vel' is not a ROS name"),
    ],
)
def test_render_refuses_what_the_agents_check_refuses(tmp_path, nodes, place, problem):
    """The agents' own launch interpreter, run over each rendered launch file; the problem is
    placed where `fleet render -o DIR` writes the file."""
    from fleet.errors import FleetError

    with pytest.raises(FleetError) as caught:
        _render_template(tmp_path, GROUP + nodes)
    line = caught.value.line()
    assert f"robot1/robot1.launch.yaml:{place}: " in line and problem in line, line
    assert "placeholder" not in line


def test_render_leaves_to_the_agent_what_only_its_computer_can_tell(tmp_path):
    """Packages, executables, environment variables and files outside the bundle are the agent's."""
    template = GROUP + (
        "  - node:\n      pkg: no_such_package\n      exec: no_such_exec\n      name: c\n"
        "      args: --home $(env NO_SUCH_VARIABLE) --share $(find-pkg-share no_such_package)\n"
        "      param: [{from: {{ params_file }}}, {from: $(find-pkg-share p)/x.yaml}, {from: /no/such.yaml}]\n"
        "  - include: {file: /no/such.launch.yaml, arg: [{name: a, value: b}]}\n"
        "  - node: {pkg: demo, exec: talker, name: d, args: $(var set_by_the_include)}\n"
    )
    expansion = _render_template(tmp_path, template)
    assert [robot.name for robot in expansion.robots] == ["robot1", "robot2"]


def test_render_refuses_a_log_level_the_nodes_would_not_start_with():
    """The built-in template passes `launch_args.log_level` to its nodes as --log-level."""
    text = spec_text(["{name: r1, launch_args: {log_level: bogus}}"], world="")
    with pytest.raises(FleetError, match=r"--log-level .bogus.: give a level \(debug, info"):
        expand_fleet(parse_spec(text, "f.yaml"))
    expand_fleet(parse_spec(spec_text(["{name: r1, launch_args: {log_level: DEBUG}}"], world=""), "f.yaml"))
