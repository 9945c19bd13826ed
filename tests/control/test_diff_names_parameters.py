"""`fleet diff` names the parameters a deploy changes, from the bundle the router keeps of what
runs (pure: an Expansion of the test fleet, status replies built here)."""

from __future__ import annotations

from pathlib import Path

import yaml

from fleet.expand import expand_fleet
from fleet.plan import build_view, diff, requests_for
from fleet.plan.discovery import DiscoveryPlan
from fleet.plan.parameters import ParameterChange, bundle_parameters, parameter_changes
from fleet.spec import load_spec
from fleet.wire import protocol as p
from tests.checkout import FLEETS

TINY = Path(__file__).parent / "data" / "tiny.yaml"

OLD = """/r/controller:
  ros__parameters:
    max_speed: 0.5
    limits: {turn: 1.0, accel: 2.0}
    gone: true
"""
NEW = """# a comment changes nothing
/r/controller:
  ros__parameters:
    max_speed: 0.8
    limits: {turn: 1.0, accel: 3.0}
    added: [1, 2]
/r/battery:
  ros__parameters: {capacity: 40.0}
"""


def test_parameters_are_read_from_params_files_only_with_nested_names_dotted():
    files = {"r.params.yaml": OLD, "r.launch.yaml": "launch: []\n", "notes.params.yaml": "{not yaml"}
    assert bundle_parameters(files) == {
        "/r/controller": {"max_speed": 0.5, "limits.turn": 1.0, "limits.accel": 2.0, "gone": True}
    }


def test_each_changed_added_and_removed_parameter_is_named():
    changes = parameter_changes({"r.params.yaml": OLD}, {"r.params.yaml": NEW})
    assert changes == [
        ParameterChange("/r/battery", "capacity", None, 40.0),
        ParameterChange("/r/controller", "added", None, [1, 2]),
        ParameterChange("/r/controller", "gone", True, None),
        ParameterChange("/r/controller", "limits.accel", 2.0, 3.0),
        ParameterChange("/r/controller", "max_speed", 0.5, 0.8),
    ]
    assert [str(change) for change in changes[2:]] == [
        "controller.gone removed (was true)",  # as ROS YAML writes it
        "controller.limits.accel 2.0 -> 3.0",
        "controller.max_speed 0.5 -> 0.8",
    ]
    assert parameter_changes({"r.params.yaml": OLD}, {"r.params.yaml": "# edited\n" + OLD}) == []
    assert str(ParameterChange("/r/controller", "frame", None, "true")) == "controller.frame = 'true' (new)"


def running(expansion, generation: int = 5, overrides: dict | None = None) -> list[p.StatusReply]:
    """Status replies of agents running every bundle of `expansion` (`overrides`: robot -> the
    values `fleet param set` gave it)."""
    replies = []
    for request in requests_for(expansion, generation, set()):
        robots = [
            p.RobotState(
                name=b.name,
                state="running",
                generation=generation,
                digest=b.digest,
                hot_digest=b.hot_digest,
                overrides=(overrides or {}).get(b.name, {}),
            )
            for b in request.bundles
        ]
        info = p.AgentInfo(name=request.agent, hostname=request.agent, cores=2, pid=1, version="0", started_at=0.0)
        replies.append(p.StatusReply(agent=info, fleet=expansion.fleet, time=0.0, generation=generation, robots=robots))
    return replies


def test_a_restart_names_the_parameter_it_changes():
    before = expand_fleet(load_spec(TINY), [])
    after = expand_fleet(load_spec(TINY), ["robot2.sleeper.period=2.0"])
    deployed = {b.name: b for request in requests_for(before, 5, set()) for b in request.bundles}
    view = build_view(running(before), [], 0.0)

    rows = {row.robot: row for row in diff(after, view, deployed)}

    assert {name: row.change for name, row in rows.items()} == {
        "robot1": "unchanged",
        "robot2": "restart",
        "robot3": "unchanged",
    }
    assert rows["robot2"].parameters == [ParameterChange("/robot2/sleeper", "period", 1.0, 2.0)]
    assert rows["robot2"].detail == "sleeper.period 1.0 -> 2.0"


def test_without_the_bundle_that_runs_a_restart_says_only_that_something_changed():
    before = expand_fleet(load_spec(TINY), [])
    after = expand_fleet(load_spec(TINY), ["robot2.sleeper.period=2.0"])
    elsewhere = expand_fleet(load_spec(TINY), ["robot2.sleeper.period=3.0"])  # the router's copy, not run
    view = build_view(running(before), [], 0.0)

    for deployed in ({}, {b.name: b for request in requests_for(elsewhere, 6, set()) for b in request.bundles}):
        row = next(row for row in diff(after, view, deployed) if row.robot == "robot2")
        assert (row.change, row.detail, row.parameters) == ("restart", "launch description or parameters changed", [])


def test_live_overrides_are_said_to_be_kept_or_dropped_as_the_agent_will():
    before = expand_fleet(load_spec(TINY), [])
    after = expand_fleet(load_spec(TINY), ["robot2.sleeper.period=2.0"])
    deployed = {b.name: b for request in requests_for(before, 5, set()) for b in request.bundles}
    overrides = {name: {f"/{name}/sleeper": {"period": 0.5}} for name in ("robot2", "robot3")}
    overrides["robot3"]["/robot3/sleeper"]["verbose"] = True
    view = build_view(running(before, overrides=overrides), [], 0.0)

    rows = {row.robot: row for row in diff(after, view, deployed)}

    assert rows["robot2"].detail == "sleeper.period 1.0 -> 2.0; live overrides dropped: /robot2/sleeper period=0.5"
    assert rows["robot3"].detail == "live overrides kept: /robot3/sleeper period=0.5; /robot3/sleeper verbose=true"


def test_a_world_update_says_what_the_world_will_do(tmp_path):
    data = yaml.safe_load((FLEETS / "two_robots.yaml").read_text())
    spec = tmp_path / "two_robots.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    before = expand_fleet(load_spec(spec), [])
    robot2 = next(r for r in data["robots"] if r["name"] == "robot2")
    robot2["pose"] = {"x": -2.0, "y": -1.5, "yaw": 0.0}
    data["robots"].append({"name": "robot3", "pose": {"x": 0.0, "y": 3.0}})
    data["world"]["obstacles"] = [o for o in data["world"]["obstacles"] if o["name"] != "crate"]
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    after = expand_fleet(load_spec(spec), [])
    deployed = {b.name: b for request in requests_for(before, 5, set()) for b in request.bundles}
    view = build_view(running(before), [], 0.0)

    rows = {row.robot: row for row in diff(after, view, deployed)}

    assert rows["world"].change == "hot-update"
    assert (
        rows["world"].detail
        == "robot2 respawns at (-2, -1.5, yaw 0); robot3 joins at (0, 3, yaw 0); obstacle crate removed"
    )
    assert (rows["robot2"].change, rows["robot3"].change) == ("unchanged", "start")


def test_robots_whose_discovery_server_would_move_are_said_to_restart():
    """Their agent restarts every unit whose environment changes, keeping live overrides.  The
    servers in use are those each agent reports, so a server whose agent is offline counts too."""
    before = expand_fleet(load_spec(TINY), [])
    overrides = {"robot1": {"/robot1/sleeper": {"period": 0.5}}}
    view = build_view(running(before, overrides=overrides), [], 0.0)
    view.servers_in_use = {"tiny": {"hostA": "10.0.0.1:7402", "hostB": "10.0.0.1:7402"}}

    same = diff(before, view, discovery=DiscoveryPlan("hostA", "10.0.0.1:7402"))
    assert {row.change for row in same} == {"unchanged"}
    moved = {row.robot: row for row in diff(before, view, discovery=DiscoveryPlan("hostB", "10.0.0.2:7402"))}
    assert {row.change for row in moved.values()} == {"restart"}
    assert moved["robot1"].detail == (
        "the fleet's DDS discovery server moves: 10.0.0.1:7402 -> 10.0.0.2:7402; "
        "live overrides kept: /robot1/sleeper period=0.5"
    )
    # A host whose address the deploy cannot know yet: the agents find it themselves.
    assert {row.change for row in diff(before, view, discovery=DiscoveryPlan("hostA", None))} == {"unchanged"}


def test_robots_running_without_a_server_are_said_to_restart_with_it():
    before = expand_fleet(load_spec(TINY), [])
    view = build_view(running(before), [], 0.0)
    view.servers_in_use = {"tiny": {"hostA": "10.0.0.1:7402", "hostB": ""}}  # hostB: still asking hostA

    rows = {row.robot: row for row in diff(before, view, discovery=DiscoveryPlan("hostA", "10.0.0.1:7402"))}

    assert {name: row.change for name, row in rows.items()} == {
        "robot1": "unchanged",
        "robot2": "restart",
        "robot3": "restart",
    }
    assert rows["robot2"].detail == "gets the fleet's DDS discovery server 10.0.0.1:7402"


def test_with_zenoh_only_the_agent_whose_own_server_would_move_restarts_its_robots():
    before = expand_fleet(load_spec(TINY), [])
    view = build_view(running(before), [], 0.0)
    view.servers_in_use = {"tiny": {"hostA": "127.0.0.1:7402", "hostB": "127.0.0.1:7403"}}
    plan = DiscoveryPlan("hostA", "127.0.0.1:7402", local={"hostA": "127.0.0.1:7402", "hostB": "127.0.0.1:7404"})

    rows = {row.robot: row for row in diff(before, view, discovery=plan)}

    assert {name: row.change for name, row in rows.items()} == {
        "robot1": "unchanged",
        "robot2": "restart",
        "robot3": "restart",
    }
    assert rows["robot2"].detail == "its DDS discovery server moves: 127.0.0.1:7403 -> 127.0.0.1:7404"


def test_status_replies_say_which_server_each_agents_robots_use():
    before = expand_fleet(load_spec(TINY), [])
    replies = running(before)
    replies[0].discovery_in_use = "10.0.0.1:7402"
    replies[1].discovery_in_use = ""
    view = build_view(replies, [], 0.0)
    assert view.servers_in_use == {"tiny": {replies[0].agent.name: "10.0.0.1:7402", replies[1].agent.name: ""}}
    assert view.only("tiny").servers_in_use == view.servers_in_use


def test_a_robot_turned_real_or_simulated_is_said_to_be(tmp_path):
    """The option only a real robot's bundle has read `simulated None -> False`."""
    data = yaml.safe_load(TINY.read_text())
    data["templates"] = str(TINY.parent / data["templates"])
    spec = tmp_path / "tiny.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    simulated = expand_fleet(load_spec(spec), [])
    data["robots"][1]["simulated"] = False
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    real = expand_fleet(load_spec(spec), [])
    for before, after, detail in (
        (simulated, real, "becomes real (simulated: false)"),
        (real, simulated, "becomes simulated"),
    ):
        deployed = {b.name: b for request in requests_for(before, 5, set()) for b in request.bundles}
        rows = {row.robot: row for row in diff(after, build_view(running(before), [], 0.0), deployed)}
        assert (rows["robot2"].change, rows["robot2"].detail) == ("restart", detail)
