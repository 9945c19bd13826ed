"""`fleet param` on a robot whose controller keeps refusing its waypoints (a route file on its
agent's computer holds 3 values), so that its agent holds it in backoff: whichever isolation runs
it, get and set fail at once, saying the node is not running and why, and list says it in one
line for the nodes that share the reason, beside the parameters of those that run.  They used to
wait for parameter services nobody served: 22 s for a get, 32 s for a set (which then said the
node `refused` the value), three lines for a list."""

from __future__ import annotations

import time

import pytest

from fleet.testing.poll import poll
from tests.control.control_helpers import DATA, robot, with_refused_route
from tests.control.control_helpers import ROUTE_REFUSAL as REFUSAL

pytestmark = pytest.mark.integration

AT_ONCE = 15.0  # s: a CLI call on a loaded machine, well short of the 20 to 30 s it waited for services
# The nodes whose process stops with the controller's: the host's robot, the composite process.
DOWN_TOGETHER = {"agent": "controller+battery", "robot": "controller+battery", "process": "controller"}
# The controller's respawn_delay here: its first backoff outlasts the three commands, each of them
# under AT_ONCE.  (With the template's 0.5 s the test waited for a sixth backoff, of 16 s by
# the count of restarts; but the doubling follows quick failures in a row, which a run of more than
# 10 s starts over, and in CI a get once came after the backoff it saw and waited 21 s.)
BACKOFF = 60.0


def param(cluster, *args):
    began = time.monotonic()
    done = cluster.cli("param", *args, "--connect", cluster.endpoint)
    return done, time.monotonic() - began


@pytest.mark.parametrize("isolation", ["agent", "robot", "process"])
def test_param_on_a_node_in_backoff_fails_at_once_saying_so(host_a, isolation):
    cluster = host_a
    site = cluster.root / f"site-{isolation}"
    template = with_refused_route(DATA / "templates" / "hosted.launch.yaml.j2", site, "robot2")
    copy = site / f"{template}.launch.yaml.j2"
    text = copy.read_text()
    assert text.index("exec: controller") < text.index("respawn_delay: 0.5")  # the controller's
    copy.write_text(text.replace("respawn_delay: 0.5", f"respawn_delay: {BACKOFF}", 1))
    spec = cluster.spec(
        name="stuck",
        fleet="stuck",
        templates=str(site),
        defaults={"template": template, "agent": "hostA", "isolation": isolation},
        robots=[{"name": "robot2"}],
    )
    outcome = cluster.deploy(spec, wait=False)
    assert outcome.ok, outcome

    def controller():
        row = robot(cluster.view("stuck"), "robot2")
        return next(node for node in row.nodes if node["name"] == "controller")

    # Between two exits a node's process runs for a moment, and a call then waits for its services
    # as for any running node.  So the commands go in as the node goes into its first backoff,
    # which lasts BACKOFF: the poll looks from the deploy on.
    poll(
        controller,
        until=lambda node: node["state"] == "backoff" and node["restarts"] == 0,
        timeout=120,
        retry_on=(StopIteration,),  # not in the view yet
        what="robot2's controller going into backoff after its first start",
    )

    got, took = param(cluster, "get", "robot2", "controller", "max_speed")
    assert got.returncode == 1 and took < AT_ONCE, (took, got.stdout + got.stderr)
    (line,) = got.stderr.splitlines()
    assert line.startswith("fleet: error: robot2/controller is not running (backoff: ") and REFUSAL in line, line

    changed, took = param(cluster, "set", "robot2", "controller", "max_speed", "0.5")
    assert changed.returncode == 1 and took < AT_ONCE, (took, changed.stdout + changed.stderr)
    assert changed.stderr == got.stderr  # not running: not a refusal, which is a node's answer
    assert "refused" not in changed.stderr

    listed, took = param(cluster, "list", "robot2")
    assert listed.returncode == 1 and took < AT_ONCE, (took, listed.stdout + listed.stderr)
    (line,) = listed.stderr.splitlines()
    down = DOWN_TOGETHER[isolation]
    assert line.startswith(f"fleet: error: robot2/{down}: not running (backoff: "), line
    # The nodes that run answer as ever.
    assert "sleeper" in listed.stdout and "period" in listed.stdout, listed.stdout
    assert ("capacity" in listed.stdout) == (isolation == "process"), listed.stdout
