"""A topic a template shares crosses agents with the `zenoh` transport: real router, two real
agents (two computers' worth of DDS on one machine: each agent runs its own discovery server on
loopback, so only the agents' bridges join them), ROS tools on each side."""

from __future__ import annotations

import json

import pytest

from fleet.testing.poll import poll
from fleet.testing.ros import RosProbe
from tests.control.control_helpers import DATA

pytestmark = pytest.mark.integration

ANNOUNCEMENTS = "/fleet/announcements"
SILENT = f"shared topic {ANNOUNCEMENTS}: no publisher on any agent for"


def shared_spec(cluster):
    return cluster.spec(
        "shared",
        fleet="shared",
        templates=str(DATA / "templates"),
        ros={"domain_id": cluster.domain_id, "use_sim_time": False, "transport": "zenoh"},
        defaults={"template": "announcer", "agent": "hostA"},
        robots=[{"name": "a1"}, {"name": "b1", "agent": "hostB"}],
    )


def test_a_shared_topic_published_on_one_agent_reaches_the_other_once(fresh_two_agents):
    from std_msgs.msg import String

    cluster = fresh_two_agents
    cluster.deploy(shared_spec(cluster), timeout=60)
    view = poll(
        lambda: cluster.view("shared"),
        until=lambda view: set(view.bridges.get("shared", {})) == {"hostA", "hostB"},
        timeout=30,
        what="a bridge on each agent",
    )
    servers = {server["agent"]: server["server"] for server in view.discovery["shared"]}
    # The robots declare it, nothing publishes it yet: status says so, in the table and in --json.
    poll(
        lambda: cluster.cli("status", "--connect", cluster.endpoint, "--fleet", "shared").stdout,
        until=lambda table: SILENT in " ".join(table.split()),
        timeout=40,
        what="the table saying that no one publishes the announcements",
    )
    status = json.loads(cluster.cli("status", "--json", "--connect", cluster.endpoint, "--fleet", "shared").stdout)
    rows = {row["name"]: row for row in status["shared_topics"]["shared"]}
    assert rows[ANNOUNCEMENTS]["problem"].startswith(SILENT)
    assert rows[ANNOUNCEMENTS]["publishers"] == {"hostA": 0, "hostB": 0}
    assert rows["/a1/status"]["problem"] and rows["/b1/status"]["problem"]
    with (
        RosProbe("on_host_a", cluster.domain_id, servers["hostA"]) as host_a,
        RosProbe("on_host_b", cluster.domain_id, servers["hostB"]) as host_b,
    ):
        heard_on_a = host_a.subscribe(ANNOUNCEMENTS, String, keep=1000)
        heard_on_b = host_b.subscribe(ANNOUNCEMENTS, String, keep=1000)

        def crossed(sender: RosProbe, receiver: RosProbe, heard, text: str) -> bool:
            sender.publish(ANNOUNCEMENTS, String(data=text))
            receiver.spin(0.2)
            return any(message.data == text for message in heard.messages)

        # The bridges start with the units: announce until one crosses.
        host_a.wait_until(
            lambda: crossed(host_a, host_b, heard_on_b, "hello"), 60, "an announcement from hostA on hostB"
        )
        host_b.wait_until(lambda: crossed(host_b, host_a, heard_on_a, "hi"), 30, "an announcement from hostB on hostA")
        # Each agent's bridge both sends the topic and brings it in: nothing may come back or circle.
        for number in range(20):
            host_a.publish(ANNOUNCEMENTS, String(data=f"from a {number}"))
            host_b.publish(ANNOUNCEMENTS, String(data=f"from b {number}"))
            host_a.spin(0.02)
            host_b.spin(0.02)
        wanted = [f"from {side} {number}" for side in "ab" for number in range(20)]

        def all_heard() -> bool:
            host_a.spin(0.1)
            host_b.spin(0.1)
            return all(
                sum(message.data == text for message in heard.messages) >= 1
                for heard in (heard_on_a, heard_on_b)
                for text in wanted
            )

        host_a.wait_until(all_heard, 30, "every announcement on both agents")
        # Publishers on both agents now (the probes'): not counted twice for a bridge's republishing.
        announcements = poll(
            lambda: {row["name"]: row for row in cluster.view("shared").shared_topics["shared"]}[ANNOUNCEMENTS],
            until=lambda row: row["publishers"] == {"hostA": 1, "hostB": 1},
            timeout=20,
            what="a publisher of the announcements on each agent",
        )
        assert announcements["problem"] == ""
        host_a.spin(2.0)
        host_b.spin(2.0)  # time for echoes to come round, were there any
        for heard in (heard_on_a, heard_on_b):
            texts = [message.data for message in heard.messages if message.data.startswith("from")]
            assert sorted(texts) == sorted(wanted)
