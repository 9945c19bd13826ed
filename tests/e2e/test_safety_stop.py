"""The safety node stops a robot before an obstacle (fleets/safety_stop.yaml: one robot whose
waypoint lies beyond a crate), and lets it go on once the obstacle is gone."""

from __future__ import annotations

import pytest

from tests.e2e.e2e_helpers import SAFETY_STOP, spec_with

pytestmark = pytest.mark.integration

CRATE_WEST_FACE = 1.75  # crate centred at x = 2.0, 0.5 m deep
ROBOT_RADIUS = 0.2


def test_safety_node_stops_the_robot_before_the_obstacle(fleet_up, tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray

    fleet = fleet_up(SAFETY_STOP)
    diagnostics = fleet.subscribe("scout", "diagnostics", DiagnosticArray)
    fleet.wait_for(lambda: fleet.pose("scout").x > 0.8, sim_timeout=10, what="scout to drive towards the crate")
    fleet.wait_for(lambda: abs(fleet.velocity("scout")[0]) < 0.01, sim_timeout=10, what="scout to stop")
    stopped = fleet.pose("scout")
    fleet.wait_sim(3.0)

    assert fleet.pose("scout").distance_to(stopped) < 0.02  # it stays stopped
    # Short of the crate, without touching it, and close to where a 0.4 m safety distance puts it.
    assert 1.0 < stopped.x < CRATE_WEST_FACE - ROBOT_RADIUS, stopped
    assert not fleet.contacts("scout")

    # It was the safety node: it reports blocking the controller's commands ...
    def safety_report():
        for message in reversed(diagnostics.messages):
            for status in message.status:
                if status.name == "/scout/safety":
                    return {value.key: value.value for value in status.values}
        return None

    report = fleet.wait_for(safety_report, sim_timeout=3, what="diagnostics of /scout/safety")
    assert int(report["gated_commands"]) > 0 and float(report["nearest_ahead"]) < 0.45, report

    # ... and with the crate taken out of the world (a hot update, nothing restarts) scout goes on.
    pids = fleet.pids("scout")
    fleet.deploy(spec_with(SAFETY_STOP, tmp_path, lambda data: data["world"].update(obstacles=[])))
    assert fleet.pids("scout") == pids
    fleet.wait_for(
        lambda: fleet.pose("scout").distance_to((4.0, 0.0)) < 0.3,
        sim_timeout=20,
        what="scout to reach its waypoint once the crate is gone",
    )
