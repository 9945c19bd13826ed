"""The fleet as `fleet status` shows it, built from one status query's replies (pure).

Agents that answer are online.  Agents the router's registry remembers but that did not answer
are offline, with the time they were last seen; their robots come from the last deploy's plan
record and show as `offline`.  Robots in the plan whose (online) agent does not run them yet
are `pending`.  The world's summary (from the agent running it) gives robot rows their pose,
velocity and battery, and each fleet with a world one WorldRow (sim time, RTF, contacts, errors).

A robot whose processes all run is `running` only when its nodes are up and its data flows: in
a fleet with a world (judge_data_flow), the world must be advancing (it publishes /clock), must
have had a cmd_vel from the robot lately (its controller runs on /clock, so that also says /clock
reaches it), and the robot's odom must have a subscriber; in every fleet, its ROS nodes must be in
the ROS graph (judge_graph: a battery or safety node stuck before joining it shows in no data the
world sees).  Otherwise it is `degraded` (or still `starting`, for a short while after its nodes
started, unless one of them has ended since) with the reason in words.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

from fleet.wire import protocol as p


@dataclass
class AgentRow:
    name: str
    online: bool
    last_seen: float | None  # seconds ago, None when never seen
    hostname: str = ""
    cores: int = 0
    backends: list[str] = field(default_factory=list)
    fleets: list[str] = field(default_factory=list)
    address: str = ""
    started_at: float = 0.0  # when its process started (time.time()); 0.0 when offline
    uptime: float | None = None  # seconds its process has run, by its own clock; None when offline


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
    restarted: int = 0  # `fleet restart`s of it carried out (its agent's count)
    generation: int = 0  # of the desired state its agent last reconciled it to
    deployed_generation: int = 0  # of the deploy that brought what it runs (the DEPLOYED column)
    digest: str = ""
    hot_digest: str = ""
    pose: dict[str, float] | None = None  # in the world frame, from the world's report
    velocity: dict[str, float] | None = None  # linear m/s, angular rad/s
    battery: float | None = None
    overrides: dict[str, dict[str, Any]] = field(default_factory=dict)
    error: str = ""
    reason: str = ""  # why the state is not `running`, in words
    nodes: list[dict[str, Any]] = field(default_factory=list)  # name, fqn, state, pid, restarts, ...
    simulated: bool = True  # False: a real robot (`simulated: false`), whose data the world does not carry

    @property
    def pids(self) -> set[int]:
        return {node["pid"] for node in self.nodes if node.get("pid")}


@dataclass
class WorldRow:
    """A fleet's world as its agent last reported it (poses go to the robot rows)."""

    fleet: str
    agent: str
    sim_time: float
    real_time_factor: float
    robots: int  # robots spawned in the world
    contacts: dict[str, Any]  # {"count", "last": [{"sim_time", "a", "b", "kind"}]}
    errors: list[dict[str, Any]]  # [{"sim_time", "message"}]: the world's current problems
    age: float | None = None  # seconds since the world last reported


@dataclass
class FleetView:
    agents: list[AgentRow]
    robots: list[RobotRow]
    generations: dict[tuple[str, str], int] = field(default_factory=dict)  # (fleet, agent) -> accepted
    domain_ids: dict[str, int] = field(default_factory=dict)
    worlds: list[WorldRow] = field(default_factory=list)  # one per fleet whose world reported
    # fleet -> {"agent", "server" ("address:port"), "pid" (None: not running)}; with the zenoh
    # transport every agent runs its own, and the list has one per agent
    discovery: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    # fleet -> agent -> the discovery server its robots use ("": none), as the agent reports it
    servers_in_use: dict[str, dict[str, str]] = field(default_factory=dict)
    bridges: dict[str, dict[str, int | None]] = field(default_factory=dict)  # fleet -> agent -> pid
    # fleet -> one entry per shared topic: {"name", "publishers" (agent -> count), "problem"}
    shared_topics: dict[str, list[dict[str, Any]]] = field(default_factory=dict)

    @property
    def service_pids(self) -> set[int]:
        """Pids of the fleets' discovery servers and bridges (processes the agents run besides units)."""
        pids = {server["pid"] for servers in self.discovery.values() for server in servers if server.get("pid")}
        return pids | {pid for agents in self.bridges.values() for pid in agents.values() if pid}

    @property
    def all_running(self) -> bool:
        return all(robot.state == "running" for robot in self.robots)

    def only(self, fleet: str) -> FleetView:
        """This view cut down to one fleet (every agent kept)."""
        return self._cut(self.robots_of(fleet), {fleet}, self.agents)

    def of_robots(self, names: list[str]) -> FleetView:
        """This view cut down to the robots named (in every fleet that has one of them), the
        agents running them, and what their fleets' worlds, servers and topics report."""
        robots = [robot for robot in self.robots if robot.name in names]
        running_them = {robot.agent for robot in robots}
        return self._cut(robots, {robot.fleet for robot in robots}, [a for a in self.agents if a.name in running_them])

    def _cut(self, robots: list[RobotRow], fleets: set[str], agents: list[AgentRow]) -> FleetView:
        """These robots and agents, and what the view has of these fleets."""
        return FleetView(
            agents=agents,
            robots=robots,
            generations={key: g for key, g in self.generations.items() if key[0] in fleets},
            domain_ids={f: d for f, d in self.domain_ids.items() if f in fleets},
            worlds=[world for world in self.worlds if world.fleet in fleets],
            discovery={f: d for f, d in self.discovery.items() if f in fleets},
            servers_in_use={f: s for f, s in self.servers_in_use.items() if f in fleets},
            bridges={f: b for f, b in self.bridges.items() if f in fleets},
            shared_topics={f: t for f, t in self.shared_topics.items() if f in fleets},
        )

    def robots_of(self, fleet: str) -> list[RobotRow]:
        return [robot for robot in self.robots if robot.fleet == fleet]

    def agents_serving(self, fleet: str) -> set[str]:
        return {agent for (f, agent) in self.generations if f == fleet}

    def find_robot(self, name: str, fleet: str | None = None) -> list[RobotRow]:
        return [r for r in self.robots if r.name == name and (fleet is None or r.fleet == fleet)]

    def to_json(self) -> dict[str, Any]:
        return {
            "agents": [_row_json(agent) for agent in self.agents],
            "robots": [_row_json(robot) for robot in self.robots],
            "worlds": [_row_json(world) for world in self.worlds],
            "discovery": self.discovery,
            "bridges": self.bridges,
            "shared_topics": self.shared_topics,
            "all_running": self.all_running,
        }


def _row_json(row: AgentRow | RobotRow | WorldRow) -> dict[str, Any]:
    # Rows hold JSON values only, so a shallow copy does (asdict deep-copies each node's dict:
    # 40 ms of `fleet status --json` at 1,000 robots).
    return {column.name: getattr(row, column.name) for column in fields(row)}


def known_fleets(statuses: list[p.StatusReply], registries: list[p.RegistryReply]) -> list[str]:
    """Fleets an agent serves or the router's registry holds (a plan, or agents seen serving it).
    The router answers a registry query for any name, and keeps only the history of a fleet that
    was taken down: neither counts."""
    served = {status.fleet for status in statuses if status.fleet}
    return sorted(served | {r.fleet for r in registries if r.plan or r.agents})


def build_view(statuses: list[p.StatusReply], registries: list[p.RegistryReply], now: float) -> FleetView:
    agents: dict[str, AgentRow] = {}
    robots: dict[tuple[str, str], RobotRow] = {}
    generations: dict[tuple[str, str], int] = {}
    domain_ids: dict[str, int] = {}
    worlds: dict[str, tuple[str, p.WorldSummary]] = {}  # fleet -> (agent, summary)
    with_world: set[str] = set()  # fleets that have a world, as their agents say
    discovery: dict[str, list[dict[str, Any]]] = {}
    servers_in_use: dict[str, dict[str, str]] = {}
    bridges: dict[str, dict[str, int | None]] = {}
    shared: dict[str, dict[str, dict[str, p.SharedTopicState]]] = {}  # fleet -> topic -> agent -> state
    placed = {  # (fleet, robot) -> the agent the last deploy put it on
        (registry.fleet, robot): agent
        for registry in registries
        if registry.plan is not None
        for robot, agent in registry.plan.robots.items()
    }

    for status in statuses:
        info = status.agent
        agent_row = agents.setdefault(
            info.name,
            AgentRow(
                info.name,
                True,
                0.0,
                info.hostname,
                info.cores,
                list(info.backends),
                address=info.address,
                started_at=info.started_at,
                uptime=max(0.0, status.time - info.started_at),  # both its clock: no skew between computers
            ),
        )
        if status.fleet is None:
            continue
        if status.fleet not in agent_row.fleets:
            agent_row.fleets.append(status.fleet)
        generations[(status.fleet, info.name)] = status.generation
        if status.domain_id is not None:
            domain_ids[status.fleet] = status.domain_id
        if status.world is not None:
            worlds[status.fleet] = (info.name, status.world)
        if status.has_world:
            with_world.add(status.fleet)
        if status.discovery_server:
            discovery.setdefault(status.fleet, []).append(
                {"agent": info.name, "server": status.discovery_server, "pid": status.discovery_pid}
            )
        if status.discovery_in_use is not None:
            servers_in_use.setdefault(status.fleet, {})[info.name] = status.discovery_in_use
        if status.bridge_pid is not None:
            bridges.setdefault(status.fleet, {})[info.name] = status.bridge_pid
        for topic in status.shared_topics:
            shared.setdefault(status.fleet, {}).setdefault(topic.name, {})[info.name] = topic
        for robot in status.robots:
            key = (status.fleet, robot.name)
            if key in robots and placed.get(key) != info.name:
                # Reported twice while it moves (its old agent still stopping it): the agent the
                # plan puts it on speaks for it, whatever order the replies came in.
                continue
            robots[key] = RobotRow(
                fleet=status.fleet,
                name=robot.name,
                kind=robot.kind,
                agent=info.name,
                state=robot.state,
                running=robot.running,
                total=robot.total,
                restarts=robot.restarts,
                restarted=robot.restarted,
                generation=robot.generation,
                # An agent that does not tell (an earlier version) has it run its generation's.
                deployed_generation=robot.deployed_generation or robot.generation,
                digest=robot.digest,
                hot_digest=robot.hot_digest,
                overrides=robot.overrides,
                error=robot.error,
                reason=robot.reason,
                nodes=[node.model_dump() for node in robot.nodes],
                simulated=robot.simulated,
            )

    for registry in registries:
        for name, seen in registry.agents.items():
            if name not in agents:
                agents[name] = AgentRow(name, False, max(0.0, now - seen.last_seen))
            if registry.fleet not in agents[name].fleets:
                agents[name].fleets.append(registry.fleet)
        if registry.plan is None:
            continue
        for robot_name, agent in registry.plan.robots.items():
            if (registry.fleet, robot_name) in robots:
                continue
            if agent not in agents:
                agents[agent] = AgentRow(agent, False, None, fleets=[registry.fleet])
            state = "pending" if agents[agent].online else "offline"
            kind = "world" if robot_name == "world" else "robot"
            row = RobotRow(registry.fleet, robot_name, kind, agent, state)
            if state == "offline":
                last_seen = agents[agent].last_seen
                row.reason = f"agent {agent} does not answer" + (
                    "" if last_seen is None else f" (last seen {last_seen:.0f} s ago)"
                )
            robots[(registry.fleet, robot_name)] = row

    for (fleet, name), row in robots.items():
        world_robot = worlds[fleet][1].robots.get(name) if fleet in worlds else None
        if world_robot is not None:
            row.pose = world_robot.pose.model_dump()
            row.velocity = world_robot.velocity.model_dump() if world_robot.velocity else None
            row.battery = world_robot.battery
    for row in robots.values():
        if not row.reason and row.error:
            row.reason = row.error
    for fleet in {fleet for fleet, _ in robots}:
        rows = [row for (f, _), row in robots.items() if f == fleet]
        world_row = robots.get((fleet, "world"))
        if world_row is not None and world_row.kind == "world":
            summary = worlds[fleet][1] if fleet in worlds else None
            judge_data_flow(rows, world_row, summary)
        elif fleet in with_world:  # its agent away, and the router without the plan that names it
            judge_data_flow(rows, None, None)
        judge_graph(rows)

    world_rows = [
        WorldRow(
            fleet=fleet,
            agent=agent,
            sim_time=world.sim_time,
            real_time_factor=world.real_time_factor,
            robots=len(world.robots),
            contacts=world.contacts.model_dump(),
            errors=[problem.model_dump() for problem in world.errors],
            age=world.age,
        )
        for fleet, (agent, world) in sorted(worlds.items())
    ]
    return FleetView(
        agents=sorted(agents.values(), key=lambda a: a.name),
        robots=sorted(robots.values(), key=lambda r: (r.fleet, r.kind != "world", r.name)),
        generations=generations,
        domain_ids=domain_ids,
        worlds=world_rows,
        discovery=discovery,
        servers_in_use=servers_in_use,
        bridges=bridges,
        shared_topics={fleet: shared_topic_rows(topics) for fleet, topics in sorted(shared.items())},
    )


SHARED_SILENT = 10.0  # s without a publisher of a shared topic on any agent before status says so
WATCH_STALE = 5.0  # s after which an agent's count of a shared topic's publishers is too old to trust


def shared_topic_rows(topics: dict[str, dict[str, p.SharedTopicState]]) -> list[dict[str, Any]]:
    """One row per shared topic of a fleet from the agents' watches (fleet.dataplane.watch), with
    a problem in words when no agent has seen a publisher of it for SHARED_SILENT (pure).  A
    watch that has not counted lately says nothing either way."""
    rows = []
    for name, states in sorted(topics.items()):
        fresh = {agent: state for agent, state in states.items() if state.age is None or state.age <= WATCH_STALE}
        row: dict[str, Any] = {
            "name": name,
            "publishers": {agent: state.publishers for agent, state in sorted(fresh.items())},
            "problem": "",
        }
        silent = [state.silent for state in fresh.values()]
        if fresh and all(s is not None for s in silent):
            quiet = min(s for s in silent if s is not None)
            if quiet >= SHARED_SILENT:
                row["problem"] = f"shared topic {name}: no publisher on any agent for {quiet:.0f} s"
        rows.append(row)
    return rows


WORLD_SILENT = 3.0  # s without a report from the world: it is not advancing (frozen, stopped)
NO_COMMANDS = 5.0  # s without a cmd_vel from a robot at the world: its data does not flow
STARTUP_GRACE = 20.0  # s after a robot's nodes started in which missing data means `starting`


def judge_data_flow(rows: list[RobotRow], world: RobotRow | None, summary: p.WorldSummary | None) -> None:
    """Turn `running` rows of one fleet into `degraded` (or `starting`) where data does not flow.

    `world` is the fleet's world row (None: nothing says where the world runs), `summary` what
    its agent last reported of it (None: no report).  Pure: only the rows' state and reason
    change."""
    world_problem = None
    if world is None:
        world_problem = "no agent that answers runs the world, and the router has no record of where it runs"
    elif world.state != "running":
        world_problem = f"the world is {world.state}" + (f" ({world.reason})" if world.reason else "")
    elif summary is None:
        world_problem = "the world has not reported yet"
        if _young(world):
            world.state, world.reason = "starting", "waiting for its first report"
        else:
            world.state, world.reason = "degraded", "it has not reported its state (see `fleet logs world`)"
    elif summary.age is not None and summary.age > WORLD_SILENT:
        world_problem = f"no /clock from the world for {summary.age:.0f} s (world not advancing)"
        world.state, world.reason = "degraded", f"not advancing: no report for {summary.age:.0f} s (frozen or stuck?)"
    for row in rows:
        if row.kind != "robot" or row.state != "running" or not row.simulated:  # a real robot: the graph judges it
            continue
        problem = world_problem
        if problem is None and summary is not None:  # without a summary there is a world problem
            problem = _robot_flow_problem(row, summary)
        if problem is None:
            continue
        # Just started and never heard by the world: still coming up.  Once its data has flowed
        # (the world has had a command from it), a stop is a fault whatever its age.
        if _young(row) and not (summary is not None and _heard_since_start(row, summary)):
            row.state, row.reason = "starting", f"waiting for data: {problem}"
        else:
            row.state, row.reason = "degraded", problem


def judge_graph(rows: list[RobotRow]) -> None:
    """Turn `running` rows of one fleet whose ROS nodes are not in the ROS graph (as their agent's
    watch sees it) into `degraded` (or `starting`, just started).  In a fleet with a world it
    comes after judge_data_flow: a robot whose data does not flow keeps that reason.

    A process can run without its node having joined the graph (stuck before or in creating it,
    as SIGKILLed participants' leftovers once made every new one); only the graph says the node
    is up.  Plain executables never join it: for a robot of only those, its processes are all
    there is to judge.  Pure: only the rows' state and reason change."""
    for row in rows:
        if row.kind != "robot" or row.state != "running":
            continue
        problem = _graph_problem(row)
        if problem is None:
            continue
        if _young(row):
            row.state, row.reason = "starting", f"waiting for its nodes: {problem}"
        else:
            row.state, row.reason = "degraded", problem


def _graph_problem(row: RobotRow) -> str | None:
    ros = [node for node in row.nodes if node.get("ros")]
    if any(node.get("in_graph") is None for node in ros):
        return f"agent {row.agent} does not see the ROS graph (its watch of the fleet is starting, or not running)"
    absent = [node.get("fqn") or node["name"] for node in ros if node.get("in_graph") is False]
    if not absent:
        return None
    more = f" (and {len(absent) - 1} more of its nodes)" if len(absent) > 1 else ""
    return f"node {absent[0]}{more} not in the ROS graph, though its process runs"


def _robot_flow_problem(row: RobotRow, summary: p.WorldSummary) -> str | None:
    robot = summary.robots.get(row.name)
    if robot is None:
        refused = [e.message for e in summary.errors if f"'{row.name}'" in e.message]
        return refused[0] if refused else "not in the world"
    if robot.cmd_age is None:
        return "no cmd_vel from it has reached the world yet"
    if robot.cmd_age > NO_COMMANDS:
        return f"no cmd_vel from it has reached the world for {robot.cmd_age:.0f} s"
    if not _heard_since_start(row, summary):
        return "no cmd_vel from its new nodes has reached the world yet"
    if robot.odom_subscribers == 0:
        return "none of its nodes receives the world's odom"
    return None


def _heard_since_start(row: RobotRow, summary: p.WorldSummary) -> bool:
    """Whether the world's last command from this robot came from its nodes running now.

    A restarted robot's world still remembers the commands of its previous processes for a few
    seconds; those say nothing about the new ones.  Both ages are durations measured when the
    status was asked (on their own computers, so no clocks are compared).  The oldest node counts:
    one node respawning alone leaves the robot's data flowing from the others."""
    robot = summary.robots.get(row.name)
    if robot is None or robot.cmd_age is None:
        return False
    uptimes = [u for u in _uptimes(row) if u > 0]
    if not uptimes:
        return True  # no start time to compare with (an agent that does not report uptimes)
    return robot.cmd_age + (summary.age or 0.0) < max(uptimes)


def _young(row: RobotRow) -> bool:
    """Its nodes started less than STARTUP_GRACE ago, each for the first time: a node restarted
    after it ended is a fault its robot recovers from (or keeps having), not a start."""
    known = _uptimes(row)
    return bool(known) and min(known) < STARTUP_GRACE and not any(node.get("restarts") for node in row.nodes)


def _uptimes(row: RobotRow) -> list[float]:
    """The uptimes its agent reported for the row's nodes (s; a node's entry may lack one)."""
    return [u for u in (node.get("uptime") for node in row.nodes) if isinstance(u, (int, float))]


def locate_world(view: FleetView, fleet: str | None = None) -> tuple[str, str]:
    """(fleet, agent) of the world to ask for its state; one clear error when there is none to ask."""
    from fleet.errors import ControlError, FleetError

    rows = [row for row in view.robots if row.kind == "world" and (fleet is None or row.fleet == fleet)]
    if not rows:
        if fleet:  # named, deployed (an unknown --fleet is refused before) and without a world: bad input
            raise FleetError(f"fleet {fleet} runs no world (its spec has none)")
        raise ControlError("no fleet with a world is deployed (see `fleet status`)")
    if len(rows) > 1:
        raise FleetError(f"several fleets run a world ({', '.join(row.fleet for row in rows)}): pick one with --fleet")
    row = rows[0]
    if row.state == "offline":
        raise ControlError(f"the world of fleet {row.fleet} runs on agent {row.agent}, which is offline")
    if row.state in ("pending", "stopped", "failed"):
        detail = f": {row.error}" if row.error else ""
        raise ControlError(f"the world of fleet {row.fleet} is not running on agent {row.agent} ({row.state}{detail})")
    return row.fleet, row.agent
