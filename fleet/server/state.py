"""An agent's state directory (laid out as fleet.rules says): desired state per fleet, persisted
before acknowledging, and units.

Writes are atomic (temporary file, fsync, rename, fsync of the directory), so a crash leaves
either the old or the new desired state, never half of one.
"""

from __future__ import annotations

import json
from functools import cached_property
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from fleet import rules
from fleet.errors import FleetError, Location
from fleet.files import write_atomic
from fleet.wire.protocol import ApplyRequest


class FleetState(BaseModel):
    """What an agent holds for one fleet."""

    request: ApplyRequest
    # Parameters set live with `fleet param set`: robot -> node fqn -> parameter -> value.
    overrides: dict[str, dict[str, dict[str, Any]]] = {}
    # Where the fleet's discovery host said it is, when the deploy named the host only (it was
    # offline then): kept so that robots started again get the server at once.
    discovery_host_address: str = ""
    # robot -> the generation of the deploy that brought its description (the DEPLOYED column):
    # a deploy leaving a robot unchanged keeps its earlier one.
    deployed: dict[str, int] = {}

    @property
    def fleet(self) -> str:
        return self.request.fleet

    @property
    def generation(self) -> int:
        return self.request.generation

    @cached_property
    def content_digest(self) -> str:  # a state is replaced, never changed: computed once
        return self.request.content_digest()


class AgentStore:
    def __init__(self, root: Path, agent: str):
        self.root = root
        self.agent = agent
        self.desired_dir = rules.desired_dir(root)

    def claim(self) -> None:
        """Create the directory; refuse one that belongs to another agent name."""
        self.root.mkdir(parents=True, exist_ok=True)
        marker = rules.agent_marker_file(self.root)
        if marker.exists():
            try:
                owner = json.loads(marker.read_text()).get("name")
            except (OSError, ValueError, AttributeError) as error:
                raise FleetError(f"not an agent's marker file ({error})", Location(marker)) from None
            if owner != self.agent:
                raise FleetError(
                    f"--state-dir {self.root}: the state directory of agent {owner!r}, not {self.agent!r} "
                    "(each agent needs a state directory of its own)"
                )
        else:
            write_atomic(marker, json.dumps({"name": self.agent}), durable=True)

    def load(self) -> tuple[dict[str, FleetState], list[str]]:
        """Every fleet's desired state; unreadable files are reported, not fatal."""
        fleets: dict[str, FleetState] = {}
        problems: list[str] = []
        if not self.desired_dir.is_dir():
            return fleets, problems
        for path in sorted(self.desired_dir.glob("*.json")):
            try:
                state = FleetState.model_validate_json(path.read_bytes())
            except Exception as error:  # a corrupt file must not keep the agent down
                problems.append(f"{path}: {error}")
                continue
            fleets[state.fleet] = state
        return fleets, problems

    def save(self, state: FleetState) -> None:
        write_atomic(self.desired_dir / f"{state.fleet}.json", state.model_dump_json(), durable=True)

    def unit_dir(self, fleet: str, robot: str) -> Path:
        return rules.unit_dir(self.root, fleet, robot)
