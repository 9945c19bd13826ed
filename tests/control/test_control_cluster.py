"""A router and two agents as separate processes on loopback, deploying the tiny test fleet.

The tests share one cluster (module fixture) and run in file order: each one states the fleet it
needs by deploying it, so a failure in one does not hide the others.
"""

from __future__ import annotations

import json
import re
import shutil
import signal
import threading
import time

import psutil
import pytest

from fleet.client import Outcome
from fleet.expand import expand_fleet
from fleet.plan import new_generation, requests_for
from fleet.rules import MAX_DOMAIN_ID, PARAMS_SUFFIX
from fleet.spec import load_spec
from fleet.testing.poll import poll
from fleet.wire import protocol as p
from fleet.wire.digests import cold_json, digest_of
from tests.control.control_helpers import DATA, robot, wait_processes_gone

pytestmark = pytest.mark.integration

ROBOTS = {"robot1": "hostA", "robot2": "hostB", "robot3": "hostB"}


def test_deploy_runs_every_robot_on_its_agent(cluster):
    outcome = cluster.deploy(cluster.spec())
    assert outcome.ok, (outcome.replies, outcome.view and outcome.view.robots)
    view = cluster.view("tiny")
    assert {row.name: row.agent for row in view.robots} == ROBOTS
    for row in view.robots:
        assert row.state == "running" and row.running == row.total == 1
        assert row.generation == outcome.generation
        assert row.pids and all(psutil.pid_exists(pid) for pid in row.pids)
    online = {agent.name: agent for agent in view.agents if agent.online}
    assert set(online) >= {"hostA", "hostB"}
    assert online["hostA"].cores >= 1 and "embedded" in online["hostA"].backends


def test_redeploy_unchanged_restarts_nothing(cluster):
    spec = cluster.spec()
    cluster.deploy(spec)
    before = {row.name: row.pids for row in cluster.view("tiny").robots}
    outcome = cluster.deploy(spec)
    assert outcome.ok and outcome.nothing_changed
    after = cluster.view("tiny")
    assert {row.name: row.pids for row in after.robots} == before
    assert all(row.generation == outcome.generation for row in after.robots)


def test_redeploy_unchanged_sends_nothing(cluster):
    spec = cluster.spec()
    first = cluster.deploy(spec)
    again = cluster.deploy(spec)
    # The agents held this content already: no apply went out, so the generation is the first one.
    assert again.ok and again.already_applied and again.replies == {}
    assert again.generation == first.generation
    assert {row.generation for row in cluster.view("tiny").robots} == {first.generation}
    # A change still goes out.
    changed = cluster.deploy(spec, sets=["robot2.sleeper.period=2.0"])
    assert changed.ok and not changed.already_applied and changed.generation > first.generation


def test_cli_redeploy_says_nothing_changed_and_status_exits_zero(cluster):
    spec = cluster.spec()
    cluster.deploy(spec)
    done = cluster.cli("deploy", str(spec), "--connect", cluster.endpoint)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "nothing changed" in done.stdout
    status = cluster.cli("status", "--json", "--connect", cluster.endpoint, "--fleet", "tiny")
    assert status.returncode == 0, status.stdout + status.stderr
    data = json.loads(status.stdout)
    assert {row["name"] for row in data["robots"]} == set(ROBOTS)
    assert data["all_running"] is True


def test_a_fleet_name_not_known_here_is_an_error_and_changes_nothing(cluster):
    cluster.deploy(cluster.spec())
    before = {row.name: row.pids for row in cluster.view("tiny").robots}
    commands = (
        ["status"],
        ["status", "--json"],
        ["status", "--watch"],
        ["down"],
        ["ros-env"],
        ["snapshot", "-o", str(cluster.root / "never.png")],
        ["dashboard", "--port", "0"],  # it served an empty fleet, all running
    )
    for command in commands:
        done = cluster.cli(*command, "--fleet", "tinny", "--connect", cluster.endpoint, timeout=30)
        assert done.returncode == 2 and done.stdout == "", done.stdout + done.stderr  # bad input, as a robot's name
        unknown = r"fleet: error: <command line>: no fleet named 'tinny' here \(fleets: .*\btiny\b.*\)\n"
        assert re.fullmatch(unknown, done.stderr), done.stderr
    # The refused down wrote nothing: the router holds no record of the name, tiny runs on as it was.
    with cluster.client() as client:
        registries = client.status("tinny")[1]
    assert [(r.plan, r.agents, r.history) for r in registries if r.fleet == "tinny"] == [(None, {}, [])]
    assert {row.name: row.pids for row in cluster.view("tiny").robots} == before


def test_changing_one_robot_restarts_only_it(cluster):
    spec = cluster.spec()
    cluster.deploy(spec)
    before = {row.name: row.pids for row in cluster.view("tiny").robots}
    same = cluster.cli("diff", str(spec), "--connect", cluster.endpoint)
    assert same.returncode == 0, same.stdout + same.stderr  # nothing to change: 0, as kubectl diff
    diff = cluster.cli("diff", str(spec), "--set", "robot2.sleeper.period=2.0", "--json", "--connect", cluster.endpoint)
    assert diff.returncode == 1, diff.stderr  # a change: 1, as kubectl diff
    rows = {row["robot"]: row for row in json.loads(diff.stdout)}
    assert {name: row["change"] for name, row in rows.items()} == {
        "robot1": "unchanged",
        "robot2": "restart",
        "robot3": "unchanged",
    }
    period = {"node": "/robot2/sleeper", "name": "period", "old": 1.0, "new": 2.0}
    assert rows["robot2"]["parameters"] == [period] and rows["robot2"]["detail"] == "sleeper.period 1.0 -> 2.0"
    table = cluster.cli("diff", str(spec), "--set", "robot2.sleeper.period=2.0", "--connect", cluster.endpoint)
    assert table.returncode == 1 and "sleeper.period 1.0 -> 2.0" in table.stdout, table.stdout
    # The spec's warnings, as render and deploy give them (on stderr: stdout stays the JSON).
    typo = cluster.cli("diff", str(spec), "--set", "robot2.sleeper.perod=2.0", "--json", "--connect", cluster.endpoint)
    assert typo.returncode == 1 and json.loads(typo.stdout), typo.stderr
    assert "warning: --set robot2.sleeper.perod=2.0: sleeper.perod is not a parameter" in typo.stderr, typo.stderr

    deployed = {row.name: row.deployed_generation for row in cluster.view("tiny").robots}
    outcome = cluster.deploy(spec, sets=["robot2.sleeper.period=2.0"])
    assert outcome.ok, (outcome.replies, outcome.view and outcome.view.robots)
    assert outcome.replies["hostB"].changes.restart == ["robot2"]
    assert outcome.replies["hostB"].changes.unchanged == ["robot3"]
    assert outcome.replies["hostA"].changes.nothing
    # DEPLOYED: the deploy that brought what each robot runs; the unchanged ones keep theirs.
    rows = cluster.view("tiny").robots
    assert {row.name: row.generation for row in rows} == dict.fromkeys(ROBOTS, outcome.generation)
    assert {row.name: row.deployed_generation for row in rows} == {**deployed, "robot2": outcome.generation}
    after = {row.name: row.pids for row in cluster.view("tiny").robots}
    assert after["robot1"] == before["robot1"] and after["robot3"] == before["robot3"]
    assert after["robot2"].isdisjoint(before["robot2"])
    assert not any(psutil.pid_exists(pid) for pid in before["robot2"])
    params = (cluster.state_dir("hostB") / "units" / "tiny" / "robot2" / "robot2.params.yaml").read_text()
    assert "period: 2.0" in params


def test_removing_a_robot_stops_it(cluster):
    cluster.deploy(cluster.spec())
    gone = robot(cluster.view("tiny"), "robot3").pids
    spec = cluster.spec(robots=[{"name": "robot1"}, {"name": "robot2", "agent": "hostB"}])
    outcome = cluster.deploy(spec)
    assert outcome.ok, (outcome.replies, outcome.view and outcome.view.robots)
    assert outcome.replies["hostB"].changes.stop == ["robot3"]
    view = cluster.view("tiny")
    assert {row.name for row in view.robots} == {"robot1", "robot2"}
    wait_processes_gone(gone, 10)
    assert not (cluster.state_dir("hostB") / "units" / "tiny" / "robot3").exists()


def test_robot_moved_to_another_agent(cluster):
    cluster.deploy(cluster.spec())
    spec = cluster.spec(robots=[{"name": "robot1"}, {"name": "robot2", "agent": "hostB"}, {"name": "robot3"}])
    outcome = cluster.deploy(spec)
    assert outcome.ok, (outcome.replies, outcome.view and outcome.view.robots)
    assert {row.name: row.agent for row in cluster.view("tiny").robots}["robot3"] == "hostA"


BAD_PAYLOADS = {
    "malformed": b"{not json",
    "truncated": None,  # filled in below from a real request
    "oversized": b"{" + b" " * (p.MAX_MESSAGE_BYTES + 1) + b"}",
    "wrong version": None,
    "path escape": None,
    "not an object": b"[1, 2, 3]",
    "empty": b"",
}


def _bad_payloads(cluster) -> dict[str, bytes | None]:
    """hostA's part of a later deploy of the tiny fleet, each spoilt in one way."""
    expansion = expand_fleet(load_spec(cluster.spec()))
    request = {r.agent: r for r in requests_for(expansion, new_generation(), set())}["hostA"]
    good = json.loads(p.encode(request))
    payloads = dict(BAD_PAYLOADS)
    raw = json.dumps(good).encode()
    payloads["truncated"] = raw[: len(raw) // 2]
    payloads["wrong version"] = json.dumps({**good, "v": 2}).encode()

    def spoilt(change) -> bytes:
        data = json.loads(raw)
        change(data, data["bundles"][0])
        return json.dumps(data).encode()

    payloads["path escape"] = spoilt(lambda _, robot: robot["files"].update({"../../evil.sh": "rm -rf /"}))
    # The agent decides what to restart by digests: one that is not its files' would hide a change.
    payloads["a digest not of its files"] = spoilt(
        lambda _, robot: robot["files"].update({robot["entry"]: "launch: []"})
    )
    # Accepted, it would hold the fleet against every later deploy (generations are time_ns).
    payloads["a generation past int64"] = spoilt(lambda data, _: data.update(generation=10**30))
    payloads["a group size of no robots"] = spoilt(
        lambda _, robot: robot["options"].update(isolation="agent", group_size="0")
    )
    payloads["a file named as the unit's logs"] = spoilt(lambda _, robot: robot["files"].update(logs="x"))
    # Its nodes would crash-loop on a parameter file rcl cannot read: refused, digest and all right.
    params = f"{good['bundles'][0]['name']}{PARAMS_SUFFIX}"

    def with_parameter_file(text: str):
        def change(_, robot) -> None:
            robot["files"][params] = text
            robot["digest"] = digest_of(cold_json(robot["entry"], robot["options"], robot["files"], robot["hot_files"]))

        return change

    payloads["a parameter file that is not YAML"] = spoilt(with_parameter_file("a: [1,"))
    payloads["a parameter file without ros__parameters"] = spoilt(
        with_parameter_file("/robot1/sleeper:\n  period: 2.0\n")
    )
    return payloads


def _settled_rows(cluster, fleet: str, timeout: float = 30.0):
    """The robots' (name, pids, generation, state) once every robot runs and two looks 1 s apart agree
    (a deploy's reply comes before every agent has finished reconciling)."""
    looks: list[list] = []

    def look():
        looks.append([(r.name, r.pids, r.generation, r.state) for r in cluster.view(fleet).robots])
        return looks[-2:]

    def settled(last_two) -> bool:
        return (
            len(last_two) == 2 and last_two[0] == last_two[1] and all(state == "running" for *_, state in last_two[1])
        )

    return poll(look, until=settled, timeout=timeout, interval=1.0, what=f"fleet {fleet} to settle")[-1]


def test_bad_messages_get_error_replies_and_leave_the_agent_intact(cluster):
    cluster.deploy(cluster.spec())
    before = _settled_rows(cluster, "tiny")
    with cluster.client() as client:
        for label, payload in _bad_payloads(cluster).items():
            replies = list(client.session.get(p.apply_key("tiny", "hostA"), payload=payload, timeout=10))
            assert len(replies) == 1, label
            assert replies[0].err is not None, label
            error = json.loads(replies[0].err.payload.to_bytes())
            assert error["kind"] == "error" and error["error"], label
            if label.startswith("a parameter file"):  # placed in the file, at its line
                assert re.search(rf"{PARAMS_SUFFIX}:\d+", error["error"]), error
    after = [(r.name, r.pids, r.generation, r.state) for r in cluster.view("tiny").robots]
    assert after == before
    assert not list(cluster.root.rglob("evil.sh"))
    assert cluster.processes["agent-hostA"].poll() is None


def test_a_restart_restarts_its_robot_alone_and_bad_restart_messages_get_error_replies(cluster):
    from fleet.client import restart

    cluster.deploy(cluster.spec())
    before = {name: (pids, state) for name, pids, _generation, state in _settled_rows(cluster, "tiny")}
    bad = {
        "malformed": b"{not json",
        "empty": b"",
        "a robot not here": p.encode(p.RestartRequest(fleet="tiny", robot="robot2")),  # robot2 runs on hostB
        "a wildcard fleet": json.dumps({"v": 1, "kind": "restart", "fleet": "*", "robot": "robot1"}).encode(),
    }
    # About fleet tiny, sent on another fleet's keys (which a router may allow a client that
    # tiny's keys are denied to): refused before anything is done.
    elsewhere = {
        "a restart": (p.restart_key("other", "hostA"), p.RestartRequest(fleet="tiny", robot="robot1")),
        "a parameter set": (
            p.param_key("other", "hostA"),
            p.ParamRequest(fleet="tiny", robot="robot1", node="sleeper", name="period", op="set", value=9.0),
        ),
        "a logs request": (p.logs_key("other", "hostA"), p.LogsRequest(fleet="tiny", robot="robot1")),
    }
    with cluster.client() as client:
        for label, payload in bad.items():
            replies = list(client.session.get(p.restart_key("tiny", "hostA"), payload=payload, timeout=10))
            assert len(replies) == 1 and replies[0].err is not None, label
            assert json.loads(replies[0].err.payload.to_bytes())["kind"] == "error", label
        for label, (key, request) in elsewhere.items():
            replies = list(client.session.get(key, payload=p.encode(request), timeout=10))
            assert len(replies) == 1 and replies[0].err is not None, label
            error = json.loads(replies[0].err.payload.to_bytes())
            assert error["code"] == "invalid" and error["error"].endswith(f"for fleet 'tiny' sent on {key}"), error
    assert {name: (pids, state) for name, pids, _generation, state in _settled_rows(cluster, "tiny")} == before

    with cluster.client() as client:
        outcome = restart(client, ["robot3"], "tiny", timeout=30)
    assert outcome.ok and outcome.asked == {("tiny", "robot3"): ("hostB", 1)}, outcome.to_json()
    after = {name: (pids, state) for name, pids, _generation, state in _settled_rows(cluster, "tiny")}
    assert not after["robot3"][0] & before["robot3"][0]
    assert after["robot1"] == before["robot1"] and after["robot2"] == before["robot2"]
    assert robot(cluster.view("tiny"), "robot3").restarted == 1


def test_a_robot_that_cannot_start_on_its_agent_leaves_the_whole_fleet_as_it_was(cluster, tmp_path):
    """kubectl-style admission: every agent is asked first whether it could start what it would
    start or change; one robot's launch file naming an executable hostB does not have stops the
    whole deploy, robot1's change on hostA included."""
    cluster.deploy(cluster.spec())
    before = _settled_rows(cluster, "tiny")
    templates = tmp_path / "templates"
    shutil.copytree(DATA / "templates", templates)
    tiny = (templates / "tiny.launch.yaml.j2").read_text()
    (templates / "typo.launch.yaml.j2").write_text(tiny.replace("exec: sleeper", "exec: sleepr"))
    shutil.copy(templates / "tiny.params.yaml", templates / "typo.params.yaml")
    robots = [{"name": "robot1"}, {"name": "robot2", "agent": "hostB"}, {"name": "robot3", "agent": "hostB"}]
    robots[2]["template"] = "typo"
    spec = cluster.spec(robots=robots, templates=str(templates))
    args = ("deploy", str(spec), "--set", "robot1.sleeper.period=2.0", "--connect", cluster.endpoint)
    done = cluster.cli(*args)
    assert done.returncode == 2, done.stdout + done.stderr
    problem, verdict = done.stderr.splitlines()
    assert problem.startswith("fleet: error: robot3 cannot start on agent hostB: robot3/robot3.launch.yaml:"), problem
    assert "executable 'sleepr' of package 'fleet_test' not found (did you mean 'sleeper'?)" in problem, problem
    assert verdict == "nothing was deployed: every robot runs as it was"
    as_json = cluster.cli(*args, "--json")
    assert as_json.returncode == 2, as_json.stdout + as_json.stderr
    data = json.loads(as_json.stdout)
    assert data["sent"] is False and data["ok"] is False and set(data["problems"]) == {"hostB"}
    assert _settled_rows(cluster, "tiny") == before


def test_a_second_fleet_in_the_same_ros_domain_is_refused_and_nothing_is_sent(cluster):
    """Two fleets in one ROS domain meet: the same topic names, and one port for both discovery
    servers (the second one's died, and its nodes used the first fleet's).  The second deploy is
    bad input; the first fleet runs on as it was."""
    cluster.deploy(cluster.spec())
    before = _settled_rows(cluster, "tiny")
    other = cluster.spec(name="other", fleet="other")
    done = cluster.cli("deploy", str(other), "--connect", cluster.endpoint)
    assert done.returncode == 2 and done.stdout == "", done.stdout + done.stderr
    assert re.fullmatch(
        rf"fleet: error: {re.escape(str(other))}:\d+:\d+: ros.domain_id {cluster.domain_id} is fleet tiny's "
        r"on this router: each fleet needs a ROS domain of its own, .*\n",
        done.stderr,
    ), done.stderr
    # `fleet diff` says so too: it shows what a deploy would do.
    diff = cluster.cli("diff", str(other), "--connect", cluster.endpoint)
    assert (diff.returncode, diff.stdout, diff.stderr) == (2, "", done.stderr)
    assert {row.fleet for row in cluster.view().robots} == {"tiny"}
    assert _settled_rows(cluster, "tiny") == before


def test_a_deploy_that_moves_the_discovery_server_says_it_restarts_the_robots(cluster):
    """Switching the transport gives every agent its own discovery server: no bundle changes, but
    each robot restarts in its new ROS environment, and the deploy says so instead of "nothing
    changed" (the agents' replies said `unchanged` while they restarted everything)."""
    cluster.deploy(cluster.spec())
    before = {row.name: row.pids for row in cluster.view("tiny").robots}
    zenoh = cluster.spec(ros={"domain_id": cluster.domain_id, "use_sim_time": False, "transport": "zenoh"})
    outcome = cluster.deploy(zenoh)
    assert outcome.ok and not outcome.nothing_changed, (outcome.replies, outcome.view and outcome.view.robots)
    assert outcome.replies["hostA"].changes.restart == ["robot1"]
    assert outcome.replies["hostB"].changes.restart == ["robot2", "robot3"]
    after = {row.name: row.pids for row in cluster.view("tiny").robots}
    assert all(after[name].isdisjoint(pids) for name, pids in before.items())


def test_older_generation_is_refused_and_told(cluster):
    expansion = expand_fleet(load_spec(cluster.spec()), ["robot1.sleeper.period=3.0"])
    older, newer = new_generation(), new_generation()
    with cluster.client() as client:
        # hostA sees the later deploy first: the earlier one arrives late and is refused.
        late = {r.agent: r for r in requests_for(expansion, older, set())}
        early = {r.agent: r for r in requests_for(expansion, newer, set())}
        assert client.send_applies([early["hostA"]])["hostA"].accepted
        refused = client.send_applies([late["hostA"]])["hostA"]
        assert not refused.accepted
        assert refused.current_generation == newer and "superseded" in refused.reason


def test_the_held_generation_again_with_other_settings_is_refused(cluster):
    expansion = expand_fleet(load_spec(cluster.spec()))
    held = {r.agent: r for r in requests_for(expansion, new_generation(), set())}["hostA"]
    other_domain = held.model_copy(update={"domain_id": (cluster.domain_id + 1) % (MAX_DOMAIN_ID + 1)})
    with cluster.client() as client:
        assert client.send_applies([held])["hostA"].accepted
        assert client.send_applies([held])["hostA"].accepted  # the same again: nothing to change
        refused = client.send_applies([other_domain])["hostA"]
        assert not refused.accepted, refused
        assert refused.reason == f"generation {held.generation} was already applied with other content"
        statuses, _ = client.status("tiny")
    assert [(s.agent.name, s.generation, s.domain_id) for s in statuses if s.agent.name == "hostA"] == [
        ("hostA", held.generation, cluster.domain_id)
    ]


def test_down_says_which_agents_refused_it_and_exits_1(fresh_two_agents):
    """An agent holding a later deploy than the `fleet down` (made on a computer whose clock is
    ahead) refuses the down: its robots go on running, and the down says so."""
    cluster = fresh_two_agents
    spec = cluster.spec()
    assert cluster.deploy(spec).ok
    ahead = new_generation() + 3600 * 10**9  # an hour ahead
    later = {r.agent: r for r in requests_for(expand_fleet(load_spec(spec)), ahead, set())}["hostA"]
    with cluster.client() as client:
        assert client.send_applies([later])["hostA"].accepted
    down = cluster.cli("down", "--fleet", "tiny", "--connect", cluster.endpoint)
    assert down.returncode == 1, down.stdout + down.stderr
    assert down.stdout == "fleet tiny: stopped on 1 of 2 agent(s)\n"
    assert down.stderr == f"tiny: hostA: refused: superseded: this agent already holds generation {ahead}\n"
    assert {r.name: r.state for r in cluster.view("tiny").robots} == {"robot1": "running"}


def test_concurrent_deploys_end_in_the_later_generation(cluster):
    specs = [cluster.spec(), cluster.spec()]
    outcomes: list[Outcome | None] = [None, None]
    sets = [["robot2.sleeper.period=4.0"], ["robot2.sleeper.period=5.0"]]

    def run(index):
        outcomes[index] = cluster.deploy(specs[index], sets=sets[index], timeout=30)

    threads = [threading.Thread(target=run, args=(index,)) for index in (0, 1)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    deployed = [outcome for outcome in outcomes if outcome is not None]
    assert len(deployed) == 2, "a deploy thread failed"
    winner = max(deployed, key=lambda outcome: outcome.generation)
    loser = min(deployed, key=lambda outcome: outcome.generation)
    assert loser.superseded_by == winner.generation or not loser.ok
    view = cluster.view("tiny")
    assert {generation for (fleet, _), generation in view.generations.items() if fleet == "tiny"} == {winner.generation}
    assert all(row.state == "running" for row in view.robots)
    expected = "5.0" if winner is outcomes[1] else "4.0"
    params = (cluster.state_dir("hostB") / "units" / "tiny" / "robot2" / "robot2.params.yaml").read_text()
    assert f"period: {expected}" in params


def test_logs_come_from_the_agent(cluster):
    cluster.deploy(cluster.spec())
    poll(
        lambda: cluster.cli("logs", "robot1", "--connect", cluster.endpoint).stdout,
        until=lambda text: "tick" in text,
        timeout=10,
        what="a tick in robot1's log",
    )

    def last_three_ticks():
        # The log file keeps earlier processes' output (robot1 was restarted by earlier tests):
        # once the running sleeper has ticked three times, --tail 3 gives exactly its last three.
        done = cluster.cli("logs", "robot1", "sleeper", "--tail", "3", "--connect", cluster.endpoint)
        assert done.returncode == 0, done.stderr
        lines = done.stdout.splitlines()
        ticks = [int(line[5:]) for line in lines if re.fullmatch(r"tick \d+", line)]
        return len(ticks) == len(lines) == 3 and ticks == list(range(ticks[0], ticks[0] + 3))

    poll(last_three_ticks, timeout=10, what="the last three lines of robot1's log to be three ticks in a row")
    missing = cluster.cli("logs", "nosuchrobot", "--connect", cluster.endpoint)
    assert missing.returncode != 0 and "nosuchrobot" in missing.stderr


def test_killed_agent_shows_offline_and_restores_its_robots(cluster):
    first = cluster.deploy(cluster.spec())
    assert first.ok
    hostb_pids = set().union(*(row.pids for row in cluster.view("tiny").robots if row.agent == "hostB"))
    killed_at = time.monotonic()
    cluster.kill("agent-hostB", signal.SIGKILL)

    def offline():
        view = cluster.view("tiny")
        agent = next((a for a in view.agents if a.name == "hostB"), None)
        return agent is not None and not agent.online and view

    view = poll(offline, timeout=3.0, what="hostB shown offline after its SIGKILL")
    assert time.monotonic() - killed_at < 3.0
    assert {row.name: row.state for row in view.robots if row.agent == "hostB"} == {
        "robot2": "offline",
        "robot3": "offline",
    }
    status = cluster.cli("status", "--connect", cluster.endpoint, "--fleet", "tiny")
    assert status.returncode != 0 and "offline" in status.stdout
    wait_processes_gone(hostb_pids, 3.0)

    # A deploy while hostB is away: hostA's robots are deployed, hostB's stay pending, exit non-zero.
    spec = cluster.spec()
    done = cluster.cli(
        "deploy", str(spec), "--connect", cluster.endpoint, "--set", "robot1.sleeper.period=1.5", "--timeout", "10"
    )
    assert done.returncode != 0 and "agent hostB is unreachable" in done.stdout, done.stdout
    assert "start it on its computer: `fleet agent --name hostB --connect tcp/ADDRESS:" in done.stderr
    view = cluster.view("tiny")
    assert robot(view, "robot1").state == "running" and robot(view, "robot1").generation > first.generation
    assert {robot(view, name).state for name in ("robot2", "robot3")} <= {"offline", "pending"}
    second = robot(view, "robot1").generation

    # Same state dir: hostB restores its robots without a deploy, then takes the deploy it missed
    # from the router (robot2 and robot3 unchanged in it: they keep running, at its generation).
    cluster.start_agent("hostB")

    def restored():
        view = cluster.view("tiny")
        rows = [row for row in view.robots if row.agent == "hostB"]
        return len(rows) == 2 and all(row.state == "running" and row.generation == second for row in rows) and view

    poll(
        restored,
        timeout=20,
        what="hostB's robots running at the missed generation",
        explain=lambda: cluster.log("agent-hostB"),
    )


def test_robots_keep_running_while_the_router_is_away(cluster):
    cluster.deploy(cluster.spec())
    pids = {row.name: row.pids for row in cluster.view("tiny").robots}
    cluster.kill("router", signal.SIGTERM)
    time.sleep(1.0)
    assert all(psutil.pid_exists(pid) for pids_ in pids.values() for pid in pids_)
    cluster.start_router()

    def back():
        view = cluster.view("tiny")
        return {row.name: row.pids for row in view.robots if row.state == "running"} == pids

    poll(
        back,
        timeout=15,
        what="the same robot processes in status again",
        explain=lambda: str(cluster.view("tiny").robots),
    )


def test_logs_follow_streams_new_lines(cluster):
    import subprocess
    import sys

    cluster.deploy(cluster.spec())
    follower = subprocess.Popen(
        [sys.executable, "-m", "fleet", "logs", "robot1", "-f", "--tail", "1", "--connect", cluster.endpoint],
        env=cluster.env,
        stdout=subprocess.PIPE,
        text=True,
    )
    output = follower.stdout
    assert output is not None
    try:
        ticks: set[str] = set()

        def ticks_read() -> int:
            line = output.readline()  # blocks until the follower prints a line
            if line.startswith("tick"):
                ticks.add(line.strip())
            return len(ticks)

        poll(ticks_read, until=lambda count: count >= 3, timeout=20, interval=0, what="three ticks from `logs -f`")
    finally:
        follower.terminate()
        follower.wait(10)
