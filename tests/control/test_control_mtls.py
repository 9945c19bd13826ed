"""A fleet on an untrusted network: `fleet certs` makes its authority, certificates and Zenoh
configs; the router demands mutual TLS and applies access rules.  Checked with real processes:
the CLI with an operator's certificate deploys; a client without a certificate, with an expired
one, with one from another fleet's authority, or with an unreadable one, is refused with a line
that says which and why; an agent's certificate reaches its own keys and no other agent's."""

from __future__ import annotations

import datetime
import json
import shutil
import time
from pathlib import Path

import psutil
import pytest

from fleet.errors import ControlError
from fleet.testing.poll import poll
from fleet.wire import certificates as c
from fleet.wire import protocol as p
from fleet.wire.session import open_client

pytestmark = pytest.mark.integration


@pytest.fixture
def secured(fresh_cluster, tmp_path):
    """`fleet certs` for the tiny fleet, and its router and agents running with them.  As the
    guide has it: `--out certs` and `--zenoh-config certs/...` relative to the directory the
    commands run in, which agents leave for their state directories."""
    cluster = fresh_cluster
    spec = cluster.spec()
    made = cluster.cli("certs", str(spec), "--out", "certs", "--json", cwd=cluster.root)
    assert made.returncode == 0, made.stdout + made.stderr
    assert {"ca.pem", "router.pem", "hostA.pem", "hostB.pem", "operator.pem"} <= set(json.loads(made.stdout)["created"])
    cluster.scheme = "tls"
    cluster.start_router(zenoh_config=Path("certs/router.json5"))  # processes start in cluster.root
    cluster.start_agent("hostA", Path("certs/agent-hostA.json5"))
    cluster.start_agent("hostB", Path("certs/agent-hostB.json5"))
    return cluster, spec, cluster.root / "certs"


def tls_router(cluster, spec, tmp_path):
    """`fleet certs` for the spec in tmp_path/certs, and the router running with them (no agent)."""
    certs = tmp_path / "certs"
    assert cluster.cli("certs", str(spec), "--out", str(certs)).returncode == 0
    cluster.scheme = "tls"
    cluster.start_router(zenoh_config=certs / "router.json5")
    return certs


def fleet_cli(cluster, *args, config=None):
    return cluster.cli(*args, "--connect", cluster.endpoint, *(["--zenoh-config", str(config)] if config else []))


def test_mutual_tls_and_access_rules(secured, tmp_path):
    cluster, spec, certs = secured
    operator = certs / "operator-operator.json5"

    def agents_online():
        status = fleet_cli(cluster, "status", "--json", config=operator)
        return status.stdout and {a["name"] for a in json.loads(status.stdout)["agents"] if a["online"]} >= {
            "hostA",
            "hostB",
        }

    poll(
        agents_online,
        timeout=20,
        what="both agents online",
        explain=lambda: cluster.log("agent-hostA") + cluster.log("router"),
    )
    deployed = fleet_cli(cluster, "deploy", str(spec), config=operator)
    assert deployed.returncode == 0, deployed.stdout + deployed.stderr

    # No certificate: refused, and the error says that is why.
    refused = fleet_cli(cluster, "status")
    assert refused.returncode == 1 and "no client certificate" in refused.stderr, refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1

    # A certificate of another fleet's authority, beside this fleet's authority.
    other = tmp_path / "other"
    c.create_authority(other, "elsewhere")
    c.issue(other, c.Member("operator"))
    mixed = json.loads(operator.read_text())
    mixed["transport"]["link"]["tls"].update(
        connect_certificate=str(other / "operator.pem"), connect_private_key=str(other / "operator.key")
    )
    (certs / "mixed.json5").write_text(json.dumps(mixed))
    refused = fleet_cli(cluster, "status", config=certs / "mixed.json5")
    assert refused.returncode == 2, refused.stderr
    assert "operator.pem" in refused.stderr and "fleet 'elsewhere'" in refused.stderr, refused.stderr

    # An expired certificate of this fleet.
    expired = tmp_path / "expired"
    expired.mkdir()
    for name in ("ca.pem", "ca.key"):
        shutil.copy(certs / name, expired / name)
    c.issue(expired, c.Member("late"), days=1, valid_from=datetime.datetime(2020, 1, 1, tzinfo=datetime.UTC))
    late = dict(mixed)
    late["transport"]["link"]["tls"].update(
        connect_certificate=str(expired / "late.pem"), connect_private_key=str(expired / "late.key")
    )
    (certs / "late.json5").write_text(json.dumps(late))
    refused = fleet_cli(cluster, "status", config=certs / "late.json5")
    assert refused.returncode == 2 and "late.pem" in refused.stderr and "expired on 2020-01-02" in refused.stderr

    # An unreadable certificate (a directory where the file should be).
    late["transport"]["link"]["tls"]["connect_certificate"] = str(expired)
    (certs / "late.json5").write_text(json.dumps(late))
    refused = fleet_cli(cluster, "status", config=certs / "late.json5")
    assert refused.returncode == 2 and "cannot read certificate" in refused.stderr, refused.stderr

    # An agent's certificate reaches its own keys only: hostA may ask its own agent for logs,
    # but neither tell hostB to remove its robots nor read the fleet's status.
    hostb_pids = {pid for row in cluster.view("tiny", operator).robots if row.agent == "hostB" for pid in row.pids}
    assert hostb_pids
    with open_client([cluster.endpoint], certs / "agent-hostA.json5") as session:
        own = list(
            session.get(
                p.logs_key("tiny", "hostA"), payload=p.encode(p.LogsRequest(fleet="tiny", robot="robot1")), timeout=5
            )
        )
        assert own and own[0].ok is not None
        empty = p.ApplyRequest(fleet="tiny", agent="hostB", generation=10**6, domain_id=cluster.domain_id, bundles=[])
        assert not list(session.get(p.apply_key("tiny", "hostB"), payload=p.encode(empty), timeout=3))
        assert not list(session.get(p.status_query("tiny"), timeout=3))
    assert all(psutil.pid_exists(pid) for pid in hostb_pids)
    hostb = [row for row in cluster.view("tiny", operator).robots if row.agent == "hostB"]
    assert {pid for row in hostb for pid in row.pids} == hostb_pids


def test_certs_command_refuses_bad_input(fresh_cluster, tmp_path):
    cluster = fresh_cluster
    spec = cluster.spec()
    certs = tmp_path / "certs"
    assert cluster.cli("certs", str(spec), "--out", str(certs)).returncode == 0
    again = cluster.cli("certs", str(spec), "--out", str(certs), "--json")
    assert again.returncode == 0 and json.loads(again.stdout)["created"] == []  # everything kept
    other = cluster.spec(name="other", fleet="other")
    refused = cluster.cli("certs", str(other), "--out", str(certs))
    assert refused.returncode == 2 and "the authority of fleet 'tiny', not 'other'" in refused.stderr, refused.stderr
    refused = cluster.cli("certs", str(spec), "--out", str(certs), "--operator", "hostA")
    assert refused.returncode == 2 and "--operator 'hostA'" in refused.stderr
    (tmp_path / "file").write_text("")
    refused = cluster.cli("certs", str(spec), "--out", str(tmp_path / "file"))
    assert refused.returncode == 2 and "not a directory" in refused.stderr


def test_refused_session_is_a_control_error(fresh_cluster, tmp_path):
    cluster = fresh_cluster
    certs = tls_router(cluster, cluster.spec(), tmp_path)
    with pytest.raises(ControlError, match="no client certificate"):
        open_client([cluster.endpoint])
    # And an agent started with another fleet's files tells which file and why, then exits.
    other = tmp_path / "other"
    c.create_authority(other, "elsewhere")
    c.issue(other, c.Member("hostA"))
    config = json.loads((certs / "agent-hostA.json5").read_text())
    config["transport"]["link"]["tls"]["connect_certificate"] = str(other / "hostA.pem")
    (certs / "bad-agent.json5").write_text(json.dumps(config))
    cluster.start_agent("hostA", certs / "bad-agent.json5")
    process = cluster.processes["agent-hostA"]
    assert process.wait(timeout=30) == 2
    assert "hostA.pem" in cluster.log("agent-hostA") and "fleet 'elsewhere'" in cluster.log("agent-hostA")


def test_deploy_before_agents_gives_every_agent_the_discovery_host_under_tls(fresh_cluster, tmp_path):
    """A deploy made while no agent is online names only the discovery host (hostA); hostB, up
    first, asks hostA's status for its address once hostA is up: the access rules must let it."""
    cluster = fresh_cluster
    spec = cluster.spec()
    certs = tls_router(cluster, spec, tmp_path)
    operator = certs / "operator-operator.json5"
    poll(  # the router listens, but its registry is declared just after
        lambda: fleet_cli(cluster, "status", config=operator).returncode == 0,
        timeout=20,
        what="the router to answer status",
    )
    deployed = fleet_cli(cluster, "deploy", str(spec), "--timeout", "2", config=operator)
    assert "hostA" in deployed.stdout + deployed.stderr, deployed.stdout + deployed.stderr  # unreachable, kept
    cluster.start_agent("hostB", certs / "agent-hostB.json5")
    time.sleep(2)  # hostB fetches its desired state and asks for hostA's address before hostA is up
    cluster.start_agent("hostA", certs / "agent-hostA.json5")

    poll(
        lambda: "its discovery server runs on agent hostA" in cluster.log("agent-hostB"),
        timeout=30,
        what="hostB to learn hostA's discovery server",
        explain=lambda: cluster.log("agent-hostB"),
    )


def test_an_agent_that_cannot_reach_the_router_says_so(fresh_cluster, tmp_path):
    """An agent keeps retrying, but says at once why it cannot connect (not on every retry)."""
    cluster = fresh_cluster  # no router: nothing listens on its port
    cluster.start_agent("hostA")
    said = f"cannot reach the fleet router at {cluster.endpoint}: "
    poll(
        lambda: said in cluster.log("agent-hostA"),
        timeout=10,
        what="the agent to say it cannot reach the router",
        explain=lambda: cluster.log("agent-hostA"),
    )
    time.sleep(3)  # retries meanwhile, every 2 s at most, with the same reason: not said again
    assert cluster.log("agent-hostA").count(said) == 1, cluster.log("agent-hostA")
    assert "retrying every 2 s" in cluster.log("agent-hostA")
    assert cluster.processes["agent-hostA"].poll() is None  # still trying
    cluster.stop_process("agent-hostA")


def test_an_agent_named_otherwise_than_its_certificate_is_refused(fresh_cluster, tmp_path):
    cluster = fresh_cluster
    certs = tls_router(cluster, cluster.spec(), tmp_path)
    cluster.start_agent("hostB", certs / "agent-hostA.json5")
    process = cluster.processes["agent-hostB"]
    assert process.wait(timeout=30) == 2
    lines = cluster.log("agent-hostB").strip().splitlines()
    said = f"--name: agent name 'hostB' is not the name in its certificate {certs / 'hostA.pem'} ('hostA')"
    assert len(lines) == 1 and lines[0].endswith(said), lines


def test_the_cli_with_an_agent_s_certificate_stops_before_sending_anything(secured):
    cluster, spec, certs = secured
    operator, agent = certs / "operator-operator.json5", certs / "agent-hostA.json5"
    # A router that holds no fleet yet answers, and so status works.
    poll(
        lambda: fleet_cli(cluster, "status", config=operator).returncode == 0,
        timeout=20,
        what="status with the operator's certificate",
    )
    said = (
        "the fleet router did not answer the status query (still starting? or access denied: the Zenoh config "
        f"in use may be an agent's, not an operator's: {agent})"
    )
    for args in (("status",), ("status", "--fleet", "tiny"), ("deploy", str(spec))):
        refused = fleet_cli(cluster, *args, config=agent)
        assert refused.returncode == 1, (args, refused.stdout, refused.stderr)
        assert refused.stderr.strip().splitlines() == [f"fleet: error: {said}"], (args, refused.stderr)
    # Nothing was sent: no plan at the router, no desired state, no robot on hostA.
    with cluster.client(operator) as client:
        _, registries = client.status("tiny")
        assert all(registry.plan is None for registry in registries)
        assert client.desired_states("tiny") == []
    assert "fleet tiny" not in cluster.log("agent-hostA"), cluster.log("agent-hostA")
