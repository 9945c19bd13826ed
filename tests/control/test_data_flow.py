"""Pure tests of what status calls `running` (data flows) and of where the discovery server runs."""

from __future__ import annotations

from typing import Literal

import pytest

from fleet.plan.discovery import DiscoveryPlan, plan_discovery
from fleet.plan.view import NO_COMMANDS, STARTUP_GRACE, WORLD_SILENT, build_view
from fleet.runtime.environment import SERVER_SLOTS, discovery_server_port, ros_environment
from fleet.wire import protocol as p

OLD = STARTUP_GRACE + 60  # node uptime long past start-up


def status(
    agent: str, robots: list[p.RobotState], world: p.WorldSummary | None = None, has_world: bool = False
) -> p.StatusReply:
    info = p.AgentInfo(name=agent, hostname=agent, cores=2, pid=1, version="0", started_at=0.0, address="10.0.0.1")
    return p.StatusReply(agent=info, fleet="f", time=0.0, generation=1, robots=robots, world=world, has_world=has_world)


def unit(name: str, *uptimes: float, state: p.RobotStateName = "running") -> p.RobotState:
    """A unit whose nodes have run `uptimes` seconds each (one node, long running, by default)."""
    kind: Literal["robot", "world"] = "world" if name == "world" else "robot"
    nodes = [p.NodeState(name=f"n{i}", state=state, pid=10 + i, uptime=u) for i, u in enumerate(uptimes or (OLD,))]
    return p.RobotState(name=name, kind=kind, state=state, nodes=nodes, running=len(nodes), total=len(nodes))


def world(age: float = 0.2, **robots: dict) -> p.WorldSummary:
    return p.WorldSummary(
        age=age, robots={name: p.WorldRobot(pose=p.Pose(x=0, y=0, yaw=0), **flow) for name, flow in robots.items()}
    )


FLOWING = {"cmd_age": 0.1, "odom_subscribers": 2}


def rows(*statuses: p.StatusReply) -> dict[str, tuple[str, str]]:
    view = build_view(list(statuses), [], now=100.0)
    return {row.name: (row.state, row.reason) for row in view.robots}


def test_a_robot_whose_data_flows_is_running():
    got = rows(status("sim", [unit("world")], world(r1=FLOWING)), status("rack", [unit("r1")]))
    assert got == {"world": ("running", ""), "r1": ("running", "")}


def test_a_silent_world_makes_every_robot_degraded_with_the_reason():
    got = rows(status("sim", [unit("world")], world(age=WORLD_SILENT + 9, r1=FLOWING)), status("rack", [unit("r1")]))
    assert got["world"][0] == "degraded" and "not advancing" in got["world"][1]
    assert got["r1"] == ("degraded", f"no /clock from the world for {WORLD_SILENT + 9:.0f} s (world not advancing)")


@pytest.mark.parametrize(
    "flow, reason",
    [
        ({"cmd_age": None, "odom_subscribers": 2}, "no cmd_vel from it has reached the world yet"),
        (
            {"cmd_age": NO_COMMANDS + 7, "odom_subscribers": 2},
            f"no cmd_vel from it has reached the world for {NO_COMMANDS + 7:.0f} s",
        ),
        ({"cmd_age": 0.1, "odom_subscribers": 0}, "none of its nodes receives the world's odom"),
    ],
)
def test_a_robot_cut_off_from_the_world_is_degraded(flow, reason):
    got = rows(status("sim", [unit("world")], world(r1=flow)), status("rack", [unit("r1")]))
    assert got["r1"] == ("degraded", reason)


def test_a_robot_just_started_without_data_yet_is_starting_not_degraded():
    got = rows(
        status("sim", [unit("world")], world(r1={"cmd_age": None, "odom_subscribers": 0})),
        status("rack", [unit("r1", 1.0)]),
    )
    assert got["r1"][0] == "starting" and got["r1"][1].startswith("waiting for data")


def test_a_robot_whose_data_flowed_is_degraded_when_it_stops_even_just_after_start():
    # Its nodes started 4 s before the world's last report, which had heard them: young, but heard.
    assert WORLD_SILENT + 6 < STARTUP_GRACE
    got = rows(
        status("sim", [unit("world")], world(age=WORLD_SILENT + 2, r1=FLOWING)),
        status("rack", [unit("r1", WORLD_SILENT + 6)]),
    )
    assert got["r1"][0] == "degraded"


def test_a_restarted_robot_is_not_running_on_its_old_processes_commands():
    # The world heard r1 0.1 s before its report, written 1.5 s ago; r1's nodes started 1 s ago.
    got = rows(status("sim", [unit("world")], world(age=1.5, r1=FLOWING)), status("rack", [unit("r1", 1.0, 0.9)]))
    assert got["r1"] == ("starting", "waiting for data: no cmd_vel from its new nodes has reached the world yet")
    # Once the world reports a command received after they started, it runs.
    got = rows(status("sim", [unit("world")], world(age=0.2, r1=FLOWING)), status("rack", [unit("r1", 1.0, 0.9)]))
    assert got["r1"] == ("running", "")


def test_a_robot_whose_node_came_back_from_an_exit_is_degraded_not_starting():
    # Its controller ended (a refused parameter, a crash) and runs again since 1 s: not a start.
    respawned = unit("r1", OLD, 1.0)
    respawned.nodes[1].restarts = 3
    got = rows(
        status("sim", [unit("world")], world(r1={"cmd_age": None, "odom_subscribers": 1})), status("rack", [respawned])
    )
    assert got["r1"] == ("degraded", "no cmd_vel from it has reached the world yet")


def test_one_respawned_node_leaves_a_robot_running_on_the_others_commands():
    got = rows(status("sim", [unit("world")], world(age=0.4, r1=FLOWING)), status("rack", [unit("r1", OLD, 0.2)]))
    assert got["r1"] == ("running", "")


def test_a_robot_the_world_did_not_spawn_says_why():
    summary = world(r1=FLOWING)
    summary.errors = [p.WorldProblem(message="robot 'r2' not spawned: overlaps obstacle 'crate'")]
    got = rows(status("sim", [unit("world")], summary), status("rack", [unit("r1"), unit("r2")]))
    assert got["r2"] == ("degraded", "robot 'r2' not spawned: overlaps obstacle 'crate'")


def test_a_world_that_never_reports_is_degraded_and_so_are_its_robots():
    got = rows(status("sim", [unit("world")]), status("rack", [unit("r1")]))
    assert got["world"] == ("degraded", "it has not reported its state (see `fleet logs world`)")
    assert got["r1"] == ("degraded", "the world has not reported yet")
    young = rows(status("sim", [unit("world", 2.0)]), status("rack", [unit("r1", 2.0)]))
    assert young["world"][0] == "starting" and young["r1"][0] == "starting"


def test_without_a_world_plain_executables_are_judged_by_their_processes():
    assert rows(status("rack", [unit("r1")])) == {"r1": ("running", "")}  # not ROS nodes: never in the graph


def ros_unit(name: str, *in_graph: bool | None, uptime: float = OLD) -> p.RobotState:
    """A robot of ROS nodes, each seen in the ROS graph by its agent's watch (True), not (False),
    or not known (None)."""
    robot = unit(name, *[uptime] * len(in_graph))
    for node, seen in zip(robot.nodes, in_graph, strict=True):
        node.ros, node.fqn, node.in_graph = True, f"/{name}/{node.name}", seen
    return robot


def test_without_a_world_a_robot_runs_when_its_ros_nodes_are_in_the_graph():
    assert rows(status("rack", [ros_unit("r1", True, True)])) == {"r1": ("running", "")}


def test_without_a_world_a_node_whose_process_runs_outside_the_graph_makes_its_robot_degraded():
    got = rows(status("rack", [ros_unit("r1", True, False), ros_unit("r2", False, False)]))
    assert got == {
        "r1": ("degraded", "node /r1/n1 not in the ROS graph, though its process runs"),
        "r2": ("degraded", "node /r2/n0 (and 1 more of its nodes) not in the ROS graph, though its process runs"),
    }


def test_without_a_world_a_robot_just_started_outside_the_graph_is_starting():
    got = rows(status("rack", [ros_unit("r1", True, False, uptime=2.0)]))
    reason = "waiting for its nodes: node /r1/n1 not in the ROS graph, though its process runs"
    assert got == {"r1": ("starting", reason)}


def test_without_a_world_a_graph_its_agent_does_not_see_is_not_taken_for_running():
    got = rows(status("rack", [ros_unit("r1", True, None)]))
    assert got == {
        "r1": ("degraded", "agent rack does not see the ROS graph (its watch of the fleet is starting, or not running)")
    }


def test_with_a_world_a_robot_whose_data_flows_is_degraded_while_a_node_of_it_is_outside_the_graph():
    # Its controller's commands reach the world; its safety node is stuck before joining the graph.
    got = rows(status("sim", [unit("world")], world(r1=FLOWING)), status("rack", [ros_unit("r1", True, False)]))
    assert got["r1"] == ("degraded", "node /r1/n1 not in the ROS graph, though its process runs")
    whole = rows(status("sim", [unit("world")], world(r1=FLOWING)), status("rack", [ros_unit("r1", True, True)]))
    assert whole["r1"] == ("running", "")


def test_with_a_world_data_that_does_not_flow_is_the_reason_before_the_graph():
    cut = {"cmd_age": NO_COMMANDS + 7, "odom_subscribers": 2}
    got = rows(status("sim", [unit("world")], world(r1=cut)), status("rack", [ros_unit("r1", True, False)]))
    assert got["r1"] == ("degraded", f"no cmd_vel from it has reached the world for {NO_COMMANDS + 7:.0f} s")


def test_with_a_world_nowhere_to_be_found_robots_in_the_graph_are_not_running():
    # The world's agent away, and a router without the plan record (a new state directory): no
    # world row.  The robots' agent still says the fleet has a world, so their data is judged.
    got = rows(status("rack", [ros_unit("r1", True, True)], has_world=True))
    assert got == {
        "r1": ("degraded", "no agent that answers runs the world, and the router has no record of where it runs")
    }


def test_robots_of_an_agent_that_does_not_answer_say_so():
    registry = p.RegistryReply(
        fleet="f",
        agents={"rack": p.AgentSeen(last_seen=96.0, online=False)},
        plan=p.PlanRecord(fleet="f", generation=1, robots={"r1": "rack", "world": "sim"}, deployed_at=0.0),
    )
    view = build_view([status("sim", [unit("world")], world())], [registry], now=100.0)
    r1 = next(row for row in view.robots if row.name == "r1")
    assert (r1.state, r1.reason) == ("offline", "agent rack does not answer (last seen 4 s ago)")


def test_the_world_agent_runs_the_discovery_server():
    plan = plan_discovery("sim", ["sim", "rack_a"], {"sim": "10.0.0.1", "rack_a": "10.0.0.2"}, 7)
    assert (plan.host, plan.server, plan.note) == ("sim", f"10.0.0.1:{discovery_server_port(7)}", "")


def test_another_online_agent_runs_it_when_the_world_agent_is_away():
    plan = plan_discovery("sim", ["sim", "rack_a"], {"rack_a": "10.0.0.2"}, 7)
    assert plan.host == "rack_a" and "sim is offline" in plan.note


def test_with_no_agent_online_the_world_agent_will_run_it_where_it_comes_up():
    plan = plan_discovery("sim", ["rack_a", "sim"], {}, 7)
    assert (plan.host, plan.server) == ("sim", None) and "agent sim runs" in plan.note
    plan = plan_discovery(None, ["rack_b", "rack_a"], {}, 7)
    assert (plan.host, plan.server) == ("rack_a", None)


def test_a_server_at_a_loopback_address_that_other_computers_need_is_said_so():
    """The world's agent reached the router through loopback (router on its computer), so it
    reports 127.0.0.1: the robots of an agent on another computer could never reach the server."""
    addresses = {"sim": "127.0.0.1", "rack_a": "10.0.0.2"}
    plan = plan_discovery("sim", ["sim", "rack_a"], addresses, 7, {"sim": "ws", "rack_a": "rack"})
    assert plan.server == f"127.0.0.1:{discovery_server_port(7)}"
    assert "at 127.0.0.1, a loopback address: the robots of rack_a on other computers cannot reach it" in plan.note
    assert "Start agent sim with --address" in plan.note
    # One name for both computers (made from one image), or names not known: rack_a reached the
    # router over the network, so it is on another computer all the same.
    for hostnames in ({"sim": "ubuntu", "rack_a": "ubuntu"}, None):
        assert (
            "the robots of rack_a on other computers"
            in plan_discovery("sim", ["sim", "rack_a"], addresses, 7, hostnames).note
        )
    # All on one computer (each reached the router through loopback): loopback is right, nothing to say.
    both_here = {"sim": "127.0.0.1", "rack_a": "127.0.0.1"}
    assert plan_discovery("sim", ["sim", "rack_a"], both_here, 7, {"sim": "ws", "rack_a": "ws"}).note == ""
    assert plan_discovery("sim", ["sim", "rack_a"], both_here, 7).note == ""
    # Said after why another agent runs it.
    moved = plan_discovery("sim", ["sim", "rack_a", "rack_b"], {"rack_a": "::1"}, 7, {"rack_a": "a", "rack_b": "b"})
    assert moved.note.startswith("agent sim is offline: agent rack_a runs the DDS discovery server; agent rack_a")
    assert "the robots of rack_b on other computers" in moved.note


def test_a_deploy_plans_the_server_from_the_agents_addresses_and_computers(tmp_path):
    """discovery_for reads what the agents report (fleet.plan.desired): the world's agent on a
    computer of its own at 127.0.0.1 gets the note a deploy prints."""
    import yaml

    from fleet.expand import expand_fleet
    from fleet.plan.desired import discovery_for
    from fleet.plan.view import AgentRow, FleetView
    from fleet.spec.load import load_spec
    from tests.checkout import FLEETS

    data = yaml.safe_load((FLEETS / "two_robots.yaml").read_text())
    data["agents"] = {"sim": {}, "rack_a": {}}
    data["defaults"]["agent"] = "rack_a"
    data["world"]["agent"] = "sim"
    spec = tmp_path / "two.yaml"
    spec.write_text(yaml.safe_dump(data))
    expansion = expand_fleet(load_spec(spec))
    agents = [
        AgentRow("sim", True, 0.1, hostname="ws", address="127.0.0.1"),
        AgentRow("rack_a", True, 0.1, hostname="rack", address="10.0.0.2"),
    ]
    plan = discovery_for(expansion, FleetView(agents=agents, robots=[]))
    assert plan.host == "sim" and "the robots of rack_a on other computers cannot reach it" in plan.note


def test_a_fleet_without_agents_has_no_server():
    assert plan_discovery(None, [], {}, 7) == DiscoveryPlan(None, None)


def test_discovery_ports_are_valid_and_distinct_for_every_domain():
    ports = [discovery_server_port(domain) for domain in range(0, 233)]
    assert len(set(ports)) == len(ports) and max(ports) < 65536


def test_nodes_of_a_fleet_with_a_server_are_its_clients_on_udp():
    env = ros_environment(
        5, base={"ROS_STATIC_PEERS": "1.2.3.4", "ROS_SUPER_CLIENT": "TRUE"}, discovery_server="10.0.0.1:8652"
    )
    assert env["ROS_DISCOVERY_SERVER"] == "10.0.0.1:8652" and env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SUBNET"
    assert (
        env["FASTDDS_BUILTIN_TRANSPORTS"] == "UDPv4" and "ROS_STATIC_PEERS" not in env and "ROS_SUPER_CLIENT" not in env
    )
    alone = ros_environment(5, base={"ROS_DISCOVERY_SERVER": "x"})
    assert alone["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST" and "ROS_DISCOVERY_SERVER" not in alone


@pytest.mark.parametrize("value", ["10.0.0.1", "host:80", "10.0.0.1:0", "10.0.0.1:99999", "999.1.1.1:80", "a\\nb:1"])
def test_a_bad_discovery_server_in_an_apply_is_refused(value):
    with pytest.raises(p.ProtocolError):
        p.decode(
            p.ApplyRequest(fleet="f", agent="a", generation=1, domain_id=1, bundles=[])
            .model_dump_json()
            .replace('"discovery_server":null', f'"discovery_server":"{value}"')
            .encode(),
            p.ApplyRequest,
        )


def test_an_agent_address_that_is_not_an_address_is_one_line_and_exit_2():
    import subprocess
    import sys

    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "fleet",
            "agent",
            "--name",
            "x",
            "--address",
            "10.0.0.300",
            "--connect",
            "tcp/127.0.0.1:1",
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2
    assert done.stderr.strip() == "fleet: error: --address: '10.0.0.300' is not an IPv4 address (such as 10.0.0.5)"


def test_zenoh_bridges_carry_each_remote_robot_both_ways_and_the_clock():
    from fleet.wire.topics import bridge_routes

    routes = bridge_routes("sim", [("a1", "/a1", "rack_a"), ("w1", "/w1", "sim"), ("b1", "/fleet/b1", "rack_b")])
    names = {
        agent: ({r.name for r in route.exports}, {r.name for r in route.imports}) for agent, route in routes.items()
    }
    assert names["sim"] == (
        {
            "/clock",
            "/a1/odom",
            "/a1/scan",
            "/a1/ground_truth",
            "/fleet/b1/odom",
            "/fleet/b1/scan",
            "/fleet/b1/ground_truth",
        },
        {"/a1/cmd_vel", "/a1/battery", "/fleet/b1/cmd_vel", "/fleet/b1/battery"},
    )
    assert names["rack_a"] == ({"/a1/cmd_vel", "/a1/battery"}, {"/clock", "/a1/odom", "/a1/scan", "/a1/ground_truth"})
    assert not any("/w1/" in name for pair in names.values() for group in pair for name in group)  # same computer
    assert bridge_routes("sim", [("w1", "/w1", "sim")]) == {"sim": p.BridgeRoutes()}
    assert bridge_routes(None, [("a1", "/a1", "rack_a")]) == {}


def test_with_zenoh_every_agent_gets_its_own_loopback_discovery_server():
    from fleet.plan.discovery import local_servers

    servers = local_servers(["sim", "rack_b", "rack_a"], 7)
    assert len(set(servers.values())) == 3 and all(s.startswith("127.0.0.1:") for s in servers.values())
    ports = {discovery_server_port(7, slot) for slot in range(SERVER_SLOTS)}
    assert {int(server.rpartition(":")[2]) for server in servers.values()} <= ports


def test_with_zenoh_an_agent_added_or_removed_moves_no_other_agents_server():
    """A moved server restarts every robot of its agent: adding a computer must not restart the world."""
    from fleet.plan.discovery import local_servers

    agents = [f"rack_{n}" for n in range(6)] + ["sim"]
    hostnames = {agent: agent for agent in agents}  # one computer each
    alone = local_servers(agents, 7, hostnames)
    for changed in (["aaa_first", *agents], agents[1:]):
        servers = local_servers(changed, 7, {**hostnames, "aaa_first": "aaa_first"})
        assert {a: servers[a] for a in alone if a in servers} == {a: alone[a] for a in servers if a in alone}


def test_with_zenoh_agents_sharing_a_computer_get_distinct_servers():
    from fleet.plan.discovery import local_servers

    agents = [f"agent{n}" for n in range(SERVER_SLOTS)]
    for hostnames in ({}, dict.fromkeys(agents, "vm")):  # unknown hostnames count as one computer
        assert len(set(local_servers(agents, 7, hostnames).values())) == SERVER_SLOTS


def test_ros_tools_get_the_fleets_domain_and_discovery_server():
    from fleet.client import tool_environment
    from fleet.errors import FleetError
    from fleet.plan import FleetView

    view = FleetView(
        agents=[],
        robots=[],
        domain_ids={"f": 7},
        discovery={"f": [{"agent": "sim", "server": "10.0.0.1:9152", "pid": 1}]},
    )
    assert tool_environment(view, None, None) == {
        "ROS_DOMAIN_ID": "7",
        "ROS_DISCOVERY_SERVER": "10.0.0.1:9152",
        "ROS_SUPER_CLIENT": "TRUE",
        "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp",
    }
    zenoh = FleetView(
        agents=[],
        robots=[],
        domain_ids={"f": 7},
        discovery={
            "f": [
                {"agent": "a", "server": "127.0.0.1:9152", "pid": 1},
                {"agent": "b", "server": "127.0.0.1:9153", "pid": 2},
            ]
        },
    )
    with pytest.raises(FleetError, match="pick the agent on this one with --agent"):
        tool_environment(zenoh, "f", None)
    assert tool_environment(zenoh, "f", "b")["ROS_DISCOVERY_SERVER"] == "127.0.0.1:9153"
    with pytest.raises(FleetError, match="several fleets"):
        tool_environment(FleetView(agents=[], robots=[], domain_ids={"f": 1, "g": 2}), None, None)


@pytest.mark.parametrize("order", [1, -1], ids=["new agent first", "old agent first"])
def test_a_robot_moving_between_agents_is_shown_on_the_agent_the_plan_puts_it_on(order):
    # Its old agent may still report it while stopping it; Zenoh delivers the replies in any order.
    replies = [status("hostA", [unit("r3", 1.0)]), status("hostB", [unit("r3", state="stopped")])][::order]
    plan = p.PlanRecord(fleet="f", generation=2, robots={"r3": "hostA"}, deployed_at=0.0)
    view = build_view(replies, [p.RegistryReply(fleet="f", plan=plan)], now=100.0)
    assert [(row.name, row.agent) for row in view.robots] == [("r3", "hostA")]


def test_a_real_robot_in_a_fleet_with_a_world_is_judged_without_the_world():
    """`simulated: false`: the world neither hosts it nor hears it, so its nodes running (and in
    the graph) are all there is to judge; a silent world degrades only the simulated robots."""
    real = unit("r2").model_copy(update={"simulated": False})
    got = rows(status("sim", [unit("world")], world(r1=FLOWING)), status("rack", [unit("r1"), real]))
    assert got == {"world": ("running", ""), "r1": ("running", ""), "r2": ("running", "")}
    silent = world(age=WORLD_SILENT + 9, r1=FLOWING)
    got = rows(status("sim", [unit("world")], silent), status("rack", [unit("r1"), real]))
    assert got["r1"][0] == "degraded" and got["r2"] == ("running", "")
