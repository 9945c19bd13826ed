"""Security by configuration: a router requiring user/password refuses clients without them."""

from __future__ import annotations

import json

import pytest

from fleet.errors import ControlError
from fleet.testing.poll import poll
from fleet.wire import protocol as p
from fleet.wire.security import ALL_MESSAGES
from fleet.wire.session import open_client

pytestmark = pytest.mark.integration


def write(path, text):
    path.write_text(text)
    return path


@pytest.fixture
def credentials(tmp_path):
    users = write(tmp_path / "users.txt", "agent:agent-secret\ndeployer:deploy-secret\ntiny:tiny-secret\n")
    # As docs/control-plane.md has it: agents and the deployer reach every fleet, the user `tiny`
    # only the keys of fleet tiny.
    everything = {"messages": ALL_MESSAGES, "flows": ["ingress", "egress"], "permission": "allow"}
    access = {
        "enabled": True,
        "default_permission": "deny",
        "rules": [
            {"id": "all", **everything, "key_exprs": ["fleet/**"]},
            {"id": "tiny", **everything, "key_exprs": ["fleet/tiny/**"]},
        ],
        "subjects": [{"id": "everyone", "usernames": ["agent", "deployer"]}, {"id": "tiny", "usernames": ["tiny"]}],
        "policies": [{"rules": ["all"], "subjects": ["everyone"]}, {"rules": ["tiny"], "subjects": ["tiny"]}],
    }
    router = {
        "transport": {
            "auth": {"usrpwd": {"user": "router", "password": "router-secret", "dictionary_file": str(users)}}
        },
        "access_control": access,
    }
    return {
        "router": write(tmp_path / "router.json5", json.dumps(router)),
        "tiny": write(
            tmp_path / "tiny.json5", '{transport: {auth: {usrpwd: {user: "tiny", password: "tiny-secret"}}}}\n'
        ),
        "agent": write(
            tmp_path / "agent.json5", '{transport: {auth: {usrpwd: {user: "agent", password: "agent-secret"}}}}\n'
        ),
        "deployer": write(
            tmp_path / "deployer.json5",
            '{transport: {auth: {usrpwd: {user: "deployer", password: "deploy-secret"}}}}\n',
        ),
        "wrong": write(
            tmp_path / "wrong.json5", '{transport: {auth: {usrpwd: {user: "deployer", password: "guess"}}}}\n'
        ),
    }


def test_clients_without_credentials_cannot_query_or_deploy(fresh_cluster, credentials):
    cluster = fresh_cluster
    cluster.start_router(zenoh_config=credentials["router"])
    cluster.start_agent("hostA", credentials["agent"])
    cluster.start_agent("hostB", credentials["agent"])

    def agents_answer():
        with cluster.client(credentials["deployer"]) as client:
            try:
                statuses, _ = client.status()
            except ControlError:  # the router listens, but its registry is not declared yet
                return False
            return {s.agent.name for s in statuses} >= {"hostA", "hostB"}

    poll(agents_answer, timeout=15, what="both agents to answer status", explain=lambda: cluster.log("agent-hostA"))

    for config in (None, credentials["wrong"]):
        with pytest.raises(ControlError, match="cannot reach"):
            open_client([cluster.endpoint], config)
    spec = cluster.spec()
    refused = cluster.cli("deploy", str(spec), "--connect", cluster.endpoint)
    assert refused.returncode != 0 and "cannot reach the fleet router" in refused.stderr
    refused = cluster.cli("status", "--connect", cluster.endpoint)
    assert refused.returncode != 0

    allowed = cluster.cli(
        "deploy", str(spec), "--connect", cluster.endpoint, "--zenoh-config", str(credentials["deployer"])
    )
    assert allowed.returncode == 0, allowed.stdout + allowed.stderr
    env = dict(cluster.env, FLEET_ZENOH_CONFIG=str(credentials["deployer"]))
    status = cluster.cli("status", "--connect", cluster.endpoint, "--json", env=env)
    assert status.returncode == 0, status.stdout + status.stderr
    with cluster.client(credentials["deployer"]) as client:
        statuses, _ = client.status("tiny")
        assert sorted(s.agent.name for s in statuses if s.fleet == "tiny") == ["hostA", "hostB"]
        assert p.status_query("tiny") == "fleet/tiny/status/**"

    # A user whose access reaches one fleet's keys only: its diff and deploy see that fleet alone
    # (the router denies them the wildcard status every fleet's domain would be checked against).
    env = dict(cluster.env, FLEET_ZENOH_CONFIG=str(credentials["tiny"]), FLEET_CONNECT=cluster.endpoint)
    diff = cluster.cli("diff", str(spec), "--set", "robot1.sleeper.period=2.0", "--json", env=env)
    assert diff.returncode == 1, diff.stdout + diff.stderr  # it would change robot1
    assert {row["robot"]: row["change"] for row in json.loads(diff.stdout)}["robot1"] == "restart"
    changed = cluster.cli("deploy", str(spec), "--set", "robot1.sleeper.period=2.0", env=env)
    assert changed.returncode == 0, changed.stdout + changed.stderr
    status = cluster.cli("status", "--fleet", "tiny", "--json", env=env)
    assert status.returncode == 0 and json.loads(status.stdout)["all_running"], status.stdout + status.stderr
