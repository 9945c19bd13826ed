"""The world over the control plane: its summary in `fleet status`, its full state for `fleet snapshot`.

Unit tests first (no network, no processes), then one integration test: a router and two agents
as processes, the world on one agent and two robots on the other, driving head-on into each other.
"""

from __future__ import annotations

import json
import struct
import subprocess
import sys
import time

import pytest
import yaml

from fleet.errors import ControlError, FleetError
from fleet.plan import build_view, locate_world
from fleet.testing.poll import poll
from fleet.wire import protocol as p
from tests.control.control_helpers import DATA, Cluster, robot

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def world_file(contacts: int = 30) -> dict:
    """A world status file as fleet/world/status.py describes it (trails, hits, many contacts)."""

    def robot_entry(x):
        return {
            "pose": {"x": x, "y": 0.0, "yaw": 0.0},
            "velocity": {"linear": 0.5, "angular": 0.0},
            "battery": 0.9,
            "model": {"type": "light", "radius": 0.2},
            "namespace": "/r",
            "trail": [[x - i * 0.01, 0.0] for i in range(60)],
            "scan_hits": [[x + 1, i * 0.01] for i in range(90)],
        }

    return {
        "fleet": "bump",
        "sim_time": 12.5,
        "wall_time": 1.0,
        "real_time_factor": 0.98,
        "physics_rate": 240.0,
        "robots": {"robot1": robot_entry(0.4), "robot2": robot_entry(0.8)},
        "obstacles": [
            {"name": "wall", "type": "box", "position": [3.0, 0.0], "yaw": 0.0, "size": [0.2, 3.0, 0.5]},
            {"name": "pillar", "type": "cylinder", "position": [0.0, 2.0], "yaw": 0.0, "radius": 0.3, "height": 1.0},
        ],
        "contacts": {
            "count": contacts,
            "last": [
                {"sim_time": float(i), "a": "robot1", "b": "robot2", "kind": "robot-robot"}
                for i in range(min(contacts, 20))
            ],
        },
        "errors": [{"sim_time": 3.0, "message": "robot 'robot3' not spawned: overlaps obstacle 'pillar'"}],
        "some_future_key": {"ignored": True},
    }


def agent_status(fleet="bump", agent="hostB", world=None, robots=("world",)) -> p.StatusReply:
    info = p.AgentInfo(name=agent, hostname="h", cores=2, pid=1, version="0", started_at=0.0)
    return p.StatusReply(
        agent=info,
        fleet=fleet,
        time=0.0,
        world=world,
        robots=[
            p.RobotState(name=name, kind="world" if name == "world" else "robot", state="running") for name in robots
        ],
    )


def test_status_summary_drops_histories_and_keeps_the_last_contacts():
    summary = p.world_summary(world_file())
    data = summary.model_dump()
    assert set(data) == {"sim_time", "real_time_factor", "age", "robots", "contacts", "errors"}
    # no trail, no scan hits
    assert set(data["robots"]["robot1"]) == {"pose", "velocity", "battery", "cmd_age", "odom_subscribers"}
    assert data["contacts"]["count"] == 30
    assert [c["sim_time"] for c in data["contacts"]["last"]] == [15.0, 16.0, 17.0, 18.0, 19.0]
    assert data["errors"][0]["message"].startswith("robot 'robot3' not spawned")
    assert len(summary.model_dump_json()) < 1500  # whatever the robots' histories


def test_world_document_validates_what_snapshot_draws():
    document = p.world_document(world_file())
    assert len(document.robots["robot1"].trail) == 60 and document.obstacles[1].radius == 0.3
    broken = world_file()
    del broken["obstacles"][1]["radius"]
    with pytest.raises(ValueError, match="cylinder needs a radius"):
        p.world_document(broken)
    broken = world_file()
    broken["robots"]["robot1"]["pose"] = {"x": "far"}
    with pytest.raises(ValueError, match=r"robots\.robot1\.pose"):
        p.world_document(broken)


def test_world_messages_round_trip_and_refuse_bad_input():
    request = p.decode(p.encode(p.WorldRequest(fleet="bump")), p.WorldRequest)
    assert request.fleet == "bump"
    assert p.world_key("bump", "hostB") == "fleet/bump/agent/hostB/world"
    with pytest.raises(p.ProtocolError) as error:
        p.decode(json.dumps({"v": 1, "kind": "world", "fleet": "../x"}).encode(), p.WorldRequest)
    assert error.value.code == "invalid"
    reply = p.WorldReply(fleet="bump", agent="hostB", world=p.world_document(world_file()))
    assert p.decode(p.encode(reply), p.WorldReply) == reply


def test_the_world_written_by_the_world_process_validates(tmp_path):
    """The protocol's models and the world's status document must not drift apart."""
    from fleet.world.app import WorldApp

    config = tmp_path / "world.yaml"
    config.write_text(
        "fleet: t\nobstacles:\n- {name: pillar, type: cylinder, position: [0.0, 2.0], radius: 0.3}\n"
        "- {name: wall, type: wall, position: [2.0, 0.0], size: [0.2, 2.0, 0.5]}\n"
        "robots:\n- {name: robot1, pose: {x: 0.0, y: 0.0}}\n- {name: robot2, pose: {x: 1.0, y: 0.0}}\n"
    )
    app = WorldApp(config, as_fast_as_possible=True)
    try:
        app.physics.command("robot1", 0.8, 0.0)
        app.run(sim_duration=2.0)
        status = app.status()
    finally:
        app.close()
    document = p.world_document(status)
    first = document.contacts.last[0]
    assert document.contacts.count >= 1 and {first.a, first.b} == {"robot1", "robot2"}
    model = document.robots["robot1"].model
    assert document.robots["robot1"].trail and model is not None and model.radius == 0.2
    assert p.world_summary(status).robots["robot2"].velocity is not None


def test_a_restarted_world_is_not_reported_from_its_predecessors_file(tmp_path):
    """The status file outlives the world process that wrote it (the next one resumes from it):
    until the new process writes, the agent reports no world rather than the dead one's robots."""
    from fleet.rules import WORLD_STATUS_FILE
    from fleet.server.units import Unit
    from fleet.wire.protocol import NodeState

    bundle = p.BundleMessage(
        name="world", kind="world", entry="w.launch.yaml", files={"w.launch.yaml": ""}, digest="ab" * 8
    )
    unit = Unit("bump", bundle, tmp_path, env={})
    uptime = 2.0  # the world's current process started 2 s ago

    def node_states():  # what the unit's launch session reports (this test runs no process)
        return [NodeState(name="world", state="running", pid=1, uptime=uptime)]

    unit.node_states = node_states  # type: ignore[method-assign]
    path = tmp_path / WORLD_STATUS_FILE
    path.write_text(json.dumps({**world_file(), "wall_time": time.time() - 2.5, "stopped": True}))
    assert unit.world_file() is None and unit.world_summary() is None  # the previous process wrote it

    path.write_text(json.dumps({**world_file(), "wall_time": time.time() - 0.5}))
    assert unit.world_file() is not None
    summary = unit.world_summary()
    assert summary is not None and summary.age is not None and summary.age < 2.0

    uptime = 0.0  # no process runs: the last status is the world's last word (its age tells)
    assert unit.world_file() is not None


def test_view_shows_worlds_and_robot_poses():
    world = p.world_summary(world_file())
    robots_agent = agent_status(agent="hostA", robots=("robot1", "robot2"))
    view = build_view([agent_status(world=world), robots_agent], [], now=0.0)
    data = view.to_json()
    assert data["worlds"] == [
        {
            "fleet": "bump",
            "agent": "hostB",
            "sim_time": 12.5,
            "real_time_factor": 0.98,
            "robots": 2,
            "contacts": world.contacts.model_dump(),
            "errors": [world.errors[0].model_dump()],
            "age": None,
        }
    ]
    row = robot(view, "robot1")
    assert row.pose == {"x": 0.4, "y": 0.0, "yaw": 0.0} and row.velocity == {"linear": 0.5, "angular": 0.0}
    assert row.battery == 0.9 and robot(view, "robot2").pose["x"] == 0.8


def test_locate_world_says_why_there_is_none_to_ask():
    assert locate_world(build_view([agent_status()], [], 0.0)) == ("bump", "hostB")
    with pytest.raises(ControlError, match="no fleet with a world"):
        locate_world(build_view([agent_status(robots=("robot1",))], [], 0.0))
    with pytest.raises(FleetError, match="fleet other runs no world") as named:
        locate_world(build_view([agent_status()], [], 0.0), "other")
    assert named.value.exit_code == 2  # named something that is not there, as the agent's not_found
    two = build_view([agent_status(), agent_status(fleet="other", agent="hostC")], [], 0.0)
    with pytest.raises(FleetError, match="several fleets run a world"):
        locate_world(two)
    assert locate_world(two, "other") == ("other", "hostC")
    plan = p.PlanRecord(fleet="bump", generation=1, robots={"world": "hostB"}, deployed_at=0.0)
    registry = p.RegistryReply(fleet="bump", plan=plan, agents={"hostB": p.AgentSeen(online=False, last_seen=0.0)})
    with pytest.raises(ControlError, match="agent hostB, which is offline"):
        locate_world(build_view([], [registry], 10.0))


def fleet_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "fleet", *args], capture_output=True, text=True, timeout=60)


def test_snapshot_refuses_bad_input_and_draws_a_local_status_file(tmp_path):
    status_file = tmp_path / "world.status.json"
    status_file.write_text(json.dumps(world_file()))
    for args, message in [
        (["-o", str(tmp_path / "w.jpg")], "name ending in .png"),
        (["-o", str(tmp_path / "missing" / "w.png")], "no such directory"),
        (["--status-file", str(status_file), "--fleet", "bump"], "does not go with --fleet"),
        (["--fleet", "no/such", "-o", str(tmp_path / "w.png")], "not a valid name"),
    ]:
        done = fleet_cli("snapshot", *args)
        assert done.returncode == 2 and message in done.stderr, (args, done.stderr)
        assert len(done.stderr.strip().splitlines()) == 1, done.stderr
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"robots": {"robot1": {"pose": {"x": 1}}}}))
    done = fleet_cli("snapshot", "--status-file", str(bad), "-o", str(tmp_path / "w.png"))
    assert done.returncode == 2 and "not a world status file" in done.stderr, done.stderr
    done = fleet_cli("snapshot", "--status-file", str(status_file), "-o", str(tmp_path / "w.png"))
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "w.png").read_bytes()[:8] == PNG_MAGIC
    # A place the picture cannot be written: said in one line, not a traceback from the PNG writer.
    folder = tmp_path / "folder.png"
    folder.mkdir()
    done = fleet_cli("snapshot", "--status-file", str(status_file), "-o", str(folder))
    assert done.returncode == 2 and done.stderr == f"fleet: error: {folder}: cannot write the picture: Is a directory\n"


# ---------------------------------------------------------------------------------------------
# Integration: real router, agents, world and robot processes.


def png_size(path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC and data[12:16] == b"IHDR", "not a PNG"
    return struct.unpack(">II", data[16:24])


@pytest.fixture(scope="module")
def bump(tmp_path_factory, domain_id):
    cluster = Cluster(tmp_path_factory.mktemp("bump"), domain_id)
    data = yaml.safe_load((DATA / "bump.yaml").read_text())
    data["ros"]["domain_id"] = domain_id
    cluster.spec_file = cluster.root / "bump.yaml"
    cluster.spec_file.write_text(yaml.safe_dump(data, sort_keys=False))
    try:
        cluster.start_router()
        cluster.start_agent("hostA")  # the robots
        cluster.start_agent("hostB")  # the world
        cluster.wait_agents_online("hostA", "hostB")
        yield cluster
    finally:
        cluster.stop()


@pytest.mark.integration
def test_robots_driving_into_each_other_show_as_contacts_and_in_a_snapshot(bump, tmp_path):
    cluster = bump
    connect = ("--connect", cluster.endpoint)
    empty = cluster.cli("snapshot", "-o", str(tmp_path / "none.png"), *connect)
    assert empty.returncode == 1 and "no fleet with a world is deployed" in empty.stderr, empty.stderr

    done = cluster.cli("deploy", str(cluster.spec_file), *connect, "--timeout", "90", timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr + cluster.log("agent-hostB")

    def bumped():
        worlds = cluster.view("bump").worlds
        return worlds and worlds[0].contacts["count"] > 0

    poll(
        bumped,
        timeout=60,
        interval=0.5,
        what="a contact in the world's status",
        explain=lambda: f"{cluster.view('bump')}\n{cluster.log('agent-hostB')}",
    )

    status = cluster.cli("status", "--json", "--fleet", "bump", *connect)
    assert status.returncode == 0, status.stdout + status.stderr
    data = json.loads(status.stdout)
    (world,) = data["worlds"]
    assert world["fleet"] == "bump" and world["agent"] == "hostB" and world["robots"] == 2
    assert world["sim_time"] > 0 and world["real_time_factor"] > 0 and world["errors"] == []
    assert world["contacts"]["count"] > 0
    assert any(
        {c["a"], c["b"]} == {"robot1", "robot2"} and c["kind"] == "robot-robot" for c in world["contacts"]["last"]
    ), world["contacts"]
    rows = {row["name"]: row for row in data["robots"]}
    assert rows["robot1"]["velocity"] is not None and rows["robot2"]["pose"] is not None
    # Neither passed through the other: robot1 (from x=0) is still left of robot2 (from x=1.5).
    assert rows["robot1"]["pose"]["x"] < rows["robot2"]["pose"]["x"], (rows["robot1"]["pose"], rows["robot2"]["pose"])
    assert "trail" not in status.stdout and "scan_hits" not in status.stdout  # the status stays small

    table = cluster.cli("status", "--fleet", "bump", *connect)
    line = next((text for text in table.stdout.splitlines() if text.startswith("world bump on hostB:")), None)
    assert line and "RTF" in line and "contact" in line, table.stdout
    assert "robot1-robot2" in line or "robot2-robot1" in line, line

    print(line)
    picture = tmp_path / "x.png"
    started = time.monotonic()
    shot = cluster.cli("snapshot", "-o", str(picture), *connect)
    assert shot.returncode == 0, shot.stdout + shot.stderr
    width, height = png_size(picture)
    assert width > 300 and height > 300 and picture.stat().st_size > 20_000
    print(f"snapshot over zenoh: {time.monotonic() - started:.2f} s, {picture.stat().st_size} bytes")

    # A fleet not deployed here is bad input, naming those that are.
    other = cluster.cli("snapshot", "--fleet", "other", "-o", str(tmp_path / "o.png"), *connect)
    assert other.returncode == 2 and "no fleet named 'other' here (fleets: bump)" in other.stderr, other.stderr
    assert not (tmp_path / "o.png").exists()
