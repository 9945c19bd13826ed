"""`fleet status` shows how long each agent's process has run, from the agent's own clock (its
reply's time minus its start): an agent that restarted shows a short time, whatever the skew
between its computer's clock and the workstation's."""

from __future__ import annotations

from fleet.cli.output import console
from fleet.cli.status_view import print_view
from fleet.plan.view import build_view
from fleet.wire import protocol as p


def status(agent: str, started_at: float, replied_at: float) -> p.StatusReply:
    info = p.AgentInfo(name=agent, hostname=agent, cores=2, pid=1, version="0", started_at=started_at)
    return p.StatusReply(agent=info, fleet=None, time=replied_at)


def test_an_agents_uptime_is_its_own_reply_time_minus_its_start(capsys):
    # rack_b's clock is an hour ahead of this computer's: its uptime is still 30 s.
    now = 1_800_000_000.0
    view = build_view([status("rack_a", now - 720, now), status("rack_b", now + 3570, now + 3600)], [], now)
    assert {row.name: row.uptime for row in view.agents} == {"rack_a": 720.0, "rack_b": 30.0}
    assert {row["name"]: row["uptime"] for row in view.to_json()["agents"]} == {"rack_a": 720.0, "rack_b": 30.0}

    print_view(view, console())
    lines = {line.split()[0]: line.split() for line in capsys.readouterr().out.splitlines() if line.startswith("rack")}
    assert lines["rack_a"][1:4] == ["online", "12", "min"], lines
    assert lines["rack_b"][1:4] == ["online", "30", "s"], lines


def test_agents_without_robots_say_none_is_deployed(capsys):
    """An empty robots table read as a failure to show them: it says there are none, and how to run some."""
    now = 1_800_000_000.0
    print_view(build_view([status("local", now - 60, now)], [], now), console())
    out = capsys.readouterr().out
    assert "Robots: none deployed (`fleet deploy SPEC` runs a fleet)" in out and "ROBOT" not in out, out
