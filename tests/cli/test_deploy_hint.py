"""What `fleet deploy` tells a user whose spec names agents that are not connected: how to start
them on their computers (the router's address filled in where the deploy knows it), or all on
this one when the router is this computer's."""

from __future__ import annotations

from fleet.cli.deploy_cmd import _start_agents_hint


def test_one_agent_with_the_routers_address():
    hint = _start_agents_hint(["rack_a"], "tcp/192.0.2.10:7447")
    assert hint == (
        "hint: agent rack_a does not answer (the router keeps its robots for it); if not running, start it "
        "on its computer: `fleet agent --name rack_a --connect tcp/192.0.2.10:7447` (docs/multi-computer.md)"
    )


def test_over_tls_the_agent_is_given_its_certificates_config():
    hint = _start_agents_hint(["rack_a"], "tls/192.0.2.10:7447")
    assert "`fleet agent --name rack_a --connect tls/192.0.2.10:7447 --zenoh-config agent-rack_a.json5`" in hint


def test_several_agents_behind_a_loopback_router():
    """The deploy reached the router on loopback: other computers need this computer's address."""
    hint = _start_agents_hint(["rack_a", "sim_host"], "tcp/127.0.0.1:7447")
    assert hint == (
        "hint: agents rack_a, sim_host do not answer (the router keeps their robots for them); if not running, "
        "start each on its computer: `fleet agent --name NAME --connect tcp/ADDRESS:7447` "
        "(ADDRESS: this computer's, on their network; docs/multi-computer.md), "
        "or all on this one: `fleet up --agent rack_a --agent sim_host`"
    )


def test_which_endpoints_are_this_computers_loopback():
    from fleet.wire.session import on_loopback

    assert [on_loopback(e) for e in ("tcp/127.0.0.1:7447", "tls/localhost:7447", "tcp/[::1]:7447")] == [True] * 3
    assert [on_loopback(e) for e in ("tcp/10.0.0.1:7447", "tcp/host-127.0.0.1.example:7447", "nonsense")] == [False] * 3


def test_a_loopback_routers_port_without_its_metadata():
    hint = _start_agents_hint(["rack_a"], "tcp/127.0.0.1:7448#iface=lo")
    assert "`fleet agent --name rack_a --connect tcp/ADDRESS:7448` (ADDRESS:" in hint
