"""The fleet as `fleet status` shows it, built from one status query's replies (pure).

Agents that answer are online.  Agents the router's registry remembers but that did not answer
are offline, with the time they were last seen; their robots come from the last deploy's plan
record and show as `offline`.  Robots in the plan whose (online) agent does not run them yet
are `pending`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from fleet.control import protocol as p


@dataclass
class AgentRow:
    name: str
    online: bool
    last_seen: float | None  # seconds ago, None when never seen
    hostname: str = ""
    cores: int = 0
    backends: list[str] = field(default_factory=list)
    fleets: list[str] = field(default_factory=list)


@dataclass
class RobotRow:
    fleet: str
    name: str
    kind: str
    agent: str
    state: str
    running: int = 0
    total: int = 0
    restarts: int = 0
    generation: int = 0
    digest: str = ""
    hot_digest: str = ""
    pose: dict[str, float] | None = None
    battery: float | None = None
    overrides: dict[str, dict[str, Any]] = field(default_factory=dict)
    error: str = ""
    nodes: list[dict[str, Any]] = field(default_factory=list)  # name, fqn, state, pid, restarts, ...

    @property
    def pids(self) -> set[int]:
        return {node["pid"] for node in self.nodes if node.get("pid")}


@dataclass
class FleetView:
    agents: list[AgentRow]
    robots: list[RobotRow]
    generations: dict[tuple[str, str], int] = field(default_factory=dict)  # (fleet, agent) -> accepted
    domain_ids: dict[str, int] = field(default_factory=dict)

    @property
    def all_running(self) -> bool:
        return all(robot.state == "running" for robot in self.robots)

    def robots_of(self, fleet: str) -> list[RobotRow]:
        return [robot for robot in self.robots if robot.fleet == fleet]

    def agents_serving(self, fleet: str) -> set[str]:
        return {agent for (f, agent) in self.generations if f == fleet}

    def find_robot(self, name: str, fleet: str | None = None) -> list[RobotRow]:
        return [r for r in self.robots if r.name == name and (fleet is None or r.fleet == fleet)]

    def to_json(self) -> dict[str, Any]:
        return {
            "agents": [asdict(agent) for agent in self.agents],
            "robots": [asdict(robot) for robot in self.robots],
            "all_running": self.all_running,
        }


def build_view(statuses: list[p.StatusReply], registries: list[p.RegistryReply], now: float) -> FleetView:
    agents: dict[str, AgentRow] = {}
    robots: dict[tuple[str, str], RobotRow] = {}
    generations: dict[tuple[str, str], int] = {}
    domain_ids: dict[str, int] = {}
    worlds: dict[str, dict] = {}

    for status in statuses:
        info = status.agent
        row = agents.setdefault(
            info.name,
            AgentRow(info.name, True, 0.0, info.hostname, info.cores, list(info.backends)),
        )
        if status.fleet is None:
            continue
        if status.fleet not in row.fleets:
            row.fleets.append(status.fleet)
        generations[(status.fleet, info.name)] = status.generation
        if status.domain_id is not None:
            domain_ids[status.fleet] = status.domain_id
        if status.world is not None:
            worlds[status.fleet] = status.world
        for robot in status.robots:
            robots[(status.fleet, robot.name)] = RobotRow(
                fleet=status.fleet, name=robot.name, kind=robot.kind, agent=info.name, state=robot.state,
                running=robot.running, total=robot.total, restarts=robot.restarts, generation=robot.generation,
                digest=robot.digest, hot_digest=robot.hot_digest, overrides=robot.overrides, error=robot.error,
                nodes=[node.model_dump() for node in robot.nodes],
            )  # fmt: skip

    for registry in registries:
        for name, seen in registry.agents.items():
            if name not in agents:
                agents[name] = AgentRow(name, False, max(0.0, now - seen.last_seen))
            if registry.fleet not in agents[name].fleets:
                agents[name].fleets.append(registry.fleet)
        if registry.plan is None:
            continue
        for robot, agent in registry.plan.robots.items():
            if (registry.fleet, robot) in robots:
                continue
            if agent not in agents:
                agents[agent] = AgentRow(agent, False, None, fleets=[registry.fleet])
            state = "pending" if agents[agent].online else "offline"
            kind = "world" if robot == "world" else "robot"
            robots[(registry.fleet, robot)] = RobotRow(registry.fleet, robot, kind, agent, state)

    for (fleet, name), row in robots.items():
        world_robot = (worlds.get(fleet) or {}).get("robots", {}).get(name)
        if isinstance(world_robot, dict):
            pose = world_robot.get("pose")
            row.pose = pose if isinstance(pose, dict) else None
            row.battery = _battery_fraction(world_robot.get("battery"))

    return FleetView(
        agents=sorted(agents.values(), key=lambda a: a.name),
        robots=sorted(robots.values(), key=lambda r: (r.fleet, r.kind != "world", r.name)),
        generations=generations,
        domain_ids=domain_ids,
    )


def _battery_fraction(value: Any) -> float | None:
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, dict):
        for key in ("percentage", "fraction", "charge"):
            if isinstance(value.get(key), (int, float)):
                return float(value[key])
    return None
