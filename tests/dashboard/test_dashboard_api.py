"""The dashboard's requests on a robot answer as HTTP does: 404 for a robot, node or parameter the
fleet does not have, 502 when the fleet fails to answer (no network here: the app is called as an
ASGI application)."""

from __future__ import annotations

import asyncio
import json
from collections.abc import MutableMapping
from typing import Any

from fleet.dashboard.live import LiveFleet
from fleet.dashboard.server import create_app
from fleet.errors import BadRequest, ControlError
from fleet.plan.view import FleetView, RobotRow


class SilentAgents:
    """A client whose agents never answer logs, and know no parameter."""

    def logs(self, agent: str, request: Any, timeout: float) -> Any:
        raise ControlError(f"agent {agent} did not answer")

    def param(self, agent: str, request: Any) -> Any:
        raise BadRequest(f"node /{request.robot}/{request.node} has no parameter {request.name!r}")


def get(live: LiveFleet, path: str) -> tuple[int, dict[str, Any]]:
    """GET `path` from the dashboard's app, without its lifespan (nothing is read from the fleet)."""
    sent: list[MutableMapping[str, Any]] = []

    async def receive() -> dict[str, Any]:
        return {"type": "http.request", "body": b"", "more_body": False}

    async def send(message: MutableMapping[str, Any]) -> None:
        sent.append(message)

    scope = {"type": "http", "method": "GET", "path": path, "headers": [], "query_string": b"", "root_path": ""}
    asyncio.run(create_app(live)(scope, receive, send))
    return sent[0]["status"], json.loads(b"".join(message.get("body", b"") for message in sent[1:]))


def test_logs_of_an_unknown_robot_are_not_found_and_of_a_silent_agent_a_bad_gateway():
    live = LiveFleet(SilentAgents())  # type: ignore[arg-type]  # only logs() is asked
    live._view = FleetView(agents=[], robots=[RobotRow("demo", "robot1", "sim", "local", "running")])
    assert get(live, "/api/logs/demo/robot9") == (404, {"error": "no robot named 'robot9' in fleet demo"})
    assert get(live, "/api/logs/other/robot1") == (404, {"error": "no robot named 'robot1' in fleet other"})
    assert get(live, "/api/params/demo/robot9")[0] == 404
    assert get(live, "/api/logs/demo/robot1") == (502, {"error": "agent local did not answer"})
    # A node or parameter the robot does not have (the agent's refusal): not found either.
    missing = {"error": "node /robot1/controller has no parameter 'nosuch'"}
    assert get(live, "/api/param/demo/robot1/controller/nosuch") == (404, missing)


def test_a_parameter_name_that_is_none_is_a_bad_request_in_words():
    live = LiveFleet(SilentAgents())  # type: ignore[arg-type]
    live._view = FleetView(agents=[], robots=[RobotRow("demo", "robot1", "sim", "local", "running")])
    status, body = get(live, "/api/param/demo/robot1/controller/bad name")
    assert status == 400 and body["error"].startswith("name: String should match pattern"), body
