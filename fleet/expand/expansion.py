"""Expand a FleetSpec into Bundles: one per robot (launch files + params file), one for the world.

Pure: reads templates, writes nothing.  Every problem is raised before any output exists, so a
failed `fleet render` or `fleet deploy` leaves nothing half-written or half-deployed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fleet.errors import Location, SpecError, TemplateError, did_you_mean, relative_to_cwd
from fleet.expand import yaml_emit
from fleet.expand.bundle import Bundle
from fleet.expand.outline import LaunchOutline, NodeOutline, outline
from fleet.expand.parameters import (
    INLINE_LAYER,
    LAYERS,
    Override,
    ParameterLayers,
    Setting,
    check_names_disjoint,
    check_type_stable,
    parse_override,
)
from fleet.expand.python_launch import python_source
from fleet.expand.rendered_launch import LaunchRenderer, params_file_reference, parse_rendered, rendered_launch_path
from fleet.expand.shared import SharedTopic, conflict
from fleet.expand.templating import TemplateSet, argument_problem, builtin_template_dirs
from fleet.nodes.parameters import ParamSpec, declared, rules
from fleet.rules import (
    LAUNCH_SUFFIX,
    PARAMS_SUFFIX,
    PYTHON_LAUNCH_SUFFIX,
    SIMULATED_OPTION,
    WORLD_DESCRIPTION,
    WORLD_TEMPLATE,
    WORLD_UNIT,
    node_name_problem,
)
from fleet.runtime.launch_file import InlineSetting
from fleet.spec.model import FleetSpec, Model, Robot
from fleet.spec.params import flatten, unflatten
from fleet.spec.rcl_types import value_text
from fleet.spec.yaml_source import DocPath, SourceMap, load_yaml, read_input
from fleet.wire.limits import MAX_BUNDLES, MAX_MESSAGE_BYTES, apply_size_bound, files_problem
from fleet.world.description import default_clock_rate, world_spec
from fleet.world.geometry import spawn_problem

if TYPE_CHECKING:
    from fleet.wire.protocol import BridgeRoutes

# Parameter layers shared by the robots of one template and node set.
SharedLayers = dict[tuple[str, frozenset[str]], ParameterLayers]


@dataclass
class RobotPlan:
    """What one robot will run, for tables, --explain and the bundle."""

    name: str
    namespace: str
    agent: str
    template: str
    isolation: str
    model: Model
    pose: dict[str, float]
    simulated: bool  # as the spec says: a robot of a fleet without a world is not hosted anywhere
    outline: LaunchOutline
    parameters: ParameterLayers
    launch_args: dict[str, str]
    launch_text: str  # the rendered .launch.yaml
    launch_python: str  # the same as a Python launch file
    shared: tuple[SharedTopic, ...] = ()  # topics its template shares (share(...))
    # node -> the parameters its launch file gives it inline after its parameter file, or at all
    # when it starts the node without the file: they win
    inline: dict[str, dict[str, InlineSetting]] = field(default_factory=dict)
    # node -> where its launch file starts it without the robot's parameter file: it gets none of it
    without_file: dict[str, Location] = field(default_factory=dict)

    def inline_setting(self, node: str, name: str) -> Setting | None:
        """The launch file's own value of a node's parameter, which wins over every layer; None
        as the value of a node started without the parameter file that the launch file does not
        give it either: it keeps its own default."""
        if found := self.inline.get(node, {}).get(name):
            return Setting(found.shown, INLINE_LAYER, str(self.launch_place(found.where)))
        if node in self.without_file and (node, name) in self.parameters.history:
            return Setting(None, INLINE_LAYER, str(self.launch_place(self.without_file[node])))
        return None

    def launch_place(self, where: Location) -> Location:
        return Location(rendered_launch_path(self.name), where.line, where.column)

    def start_value(self, node: str, name: str) -> Any:
        """The value of a node's parameter the node starts with, as far as render can tell: the
        launch file's inline one (rcl applies it last), else the parameter file's; None where the
        node keeps its own default, or only the agent's computer can tell (`$(env ...)`)."""
        if found := self.inline.get(node, {}).get(name):
            return found.value if found.known else None
        settings = self.parameters.history.get((node, name))
        return settings[-1].value if settings and node not in self.without_file else None

    @property
    def on_sim_time(self) -> bool:
        """Whether a node of it starts with use_sim_time true, and so takes its time from /clock."""
        return any(self.start_value(node.name, "use_sim_time") is True for node in self.outline.nodes)


@dataclass
class Expansion:
    spec: FleetSpec
    robots: list[RobotPlan]
    bundles: list[Bundle]
    bridge: dict[str, BridgeRoutes] = field(default_factory=dict)  # per agent, with the `zenoh` transport
    warnings: list[str] = field(default_factory=list)

    @property
    def fleet(self) -> str:
        return self.spec.fleet

    @property
    def domain_id(self) -> int:
        return self.spec.ros.domain_id

    @property
    def transport(self) -> str:
        return self.spec.ros.transport

    def for_agent(self, agent: str) -> list[Bundle]:
        return [bundle for bundle in self.bundles if bundle.agent == agent]

    # Lookups by name: indexed once, since a table of every robot asks for each one (an
    # expansion is not changed once made).
    @cached_property
    def _bundles_by_name(self) -> dict[str, Bundle]:
        return {bundle.name: bundle for bundle in self.bundles}

    @cached_property
    def _robots_by_name(self) -> dict[str, RobotPlan]:
        return {robot.name: robot for robot in self.robots}

    def shared_topics(self, agent: str) -> list[SharedTopic]:
        """The topics the robots of `agent` share, one per name."""
        topics = {topic.name: topic for robot in self.robots if robot.agent == agent for topic in robot.shared}
        return [topics[name] for name in sorted(topics)]

    def bundle(self, name: str) -> Bundle | None:
        return self._bundles_by_name.get(name)

    def robot(self, name: str) -> RobotPlan | None:
        return self._robots_by_name.get(name)


def template_set_for(spec: FleetSpec) -> TemplateSet:
    directories = []
    if spec.templates is not None:
        try:
            directories.append((Path(spec.source_file).parent / spec.templates).resolve())
            problem = None if directories[0].is_dir() else "is not a directory" if directories[0].exists() else ""
        except (OSError, ValueError):  # a NUL in the name, a loop of links
            problem = ""
        if problem is not None:
            raise SpecError(
                f"templates directory {spec.templates} {problem or 'does not exist'}",
                _spec_location(spec, ("templates",)),
            )
    # Read within this command, whose working directory stays: relative paths name them in messages.
    return TemplateSet([relative_to_cwd(directory) for directory in directories + builtin_template_dirs()])


def expand_fleet(spec: FleetSpec, sets: list[str] | tuple[str, ...] = ()) -> Expansion:
    _check_units_per_agent(spec)
    templates = template_set_for(spec)
    overrides = [parse_override(text) for text in sets]
    shared_layers: SharedLayers = {}  # per template and node set
    renderer = LaunchRenderer(templates, spec.fleet)
    robots = [
        _plan_robot(spec, index, robot, templates, renderer, shared_layers) for index, robot in enumerate(spec.robots)
    ]
    _apply_overrides(spec, robots, overrides)
    _check_default_nodes(spec, robots)
    _check_shared(spec, robots, templates)
    # One warning per parameter name a template does not know, or gives inline, however many
    # robots set it.
    unknown: dict[tuple[str, str, str], list[str]] = {}
    checked: set[int] = set()  # shared layers checked with a robot: the next ones check only what they changed
    values_checked: dict[str, set[Any]] = {}  # see _check_node_values
    for plan in robots:
        layers = plan.parameters
        nodes = layers.changed if id(layers.origin) in checked else None
        check_type_stable(layers, plan.name, nodes)
        check_names_disjoint(layers, plan.name, nodes)
        _check_node_values(plan, values_checked)
        for (node, name), warning in layers.unknown_to_template(nodes).items():
            if name not in plan.inline.get(node, {}):  # known to the launch file: warned below
                unknown.setdefault((plan.template, node, name), []).append(warning)
        for (node, name), warning in _unused_for_inline(plan).items():
            unknown.setdefault((plan.template, node, name), []).append(warning)
        for node, warning in _unread_for_lack_of_file(plan).items():
            unknown.setdefault((plan.template, node, ""), []).append(warning)  # one for the whole node
        checked.add(id(layers.origin))
    sections: dict[DocPath, str] = {}
    bundles = [_robot_bundle(spec, plan, sections) for plan in robots]
    if spec.world is not None:
        bundles.append(_world_bundle(spec, templates))
    bridge = _bridge_routes(spec, bundles, robots)
    _check_deliverable(spec, bundles, bridge)
    warnings = sorted(_once(found) for found in unknown.values()) + _misnamed_defaults(templates, robots)
    warnings += _sim_time_without_world(spec, robots)
    return Expansion(spec=spec, robots=robots, bundles=bundles, bridge=bridge, warnings=warnings)


def _check_node_values(plan: RobotPlan, checked: dict[str, set[Any]]) -> None:
    """Refuse values one of fleet's own nodes (package fleet_nodes) would refuse at start, by its
    own declarations and rules (fleet.nodes.parameters, which the node declares and checks by): a
    value of another type than declared or out of its range, at the place the value the node gets
    is written (the spec, --set, the template's defaults, or the launch file when it gives the
    parameter inline); then the node's values together, as it has them (its defaults filled in),
    by its rules (_check_together).  A node of another package is left alone: fleet cannot know
    its parameters; so is a value only the agent's computer can tell (a `$(env ...)` inline).

    Cheap for 10,000 robots: `checked` holds, per executable, the nodes of shared layers already
    checked and each history of a value already checked (robots share the histories of values
    they do not change), so each value is checked once, not once per robot."""
    layers = plan.parameters
    for node in plan.outline.nodes:
        specs = declared(node.package, node.executable)
        if specs is None:
            continue
        inline = plan.inline.get(node.name, {})
        for name, given in inline.items():
            if (spec := specs.get(name)) is not None and given.known and (problem := spec.problem(given.value)):
                raise SpecError(_refused_value(plan, node, name, problem), plan.launch_place(given.where))
        if node.name in plan.without_file:  # none of the parameter file reaches it
            _check_together(plan, node, specs, {})
            continue
        seen = checked.get(node.executable)
        if seen is None:
            seen = checked[node.executable] = set()
        if layers.same_as_origin(node.name):
            # Inline values may differ by robot (a template writes {{ robot.name }} into one).
            key = (id(layers.origin), node.name, tuple((name, repr(given.value)) for name, given in inline.items()))
            if key in seen:
                continue
            seen.add(key)
        from_file = {}
        for name, spec in specs.items():
            settings = layers.history.get((node.name, name))
            # None: the node keeps its own default; inline: the launch file's value, checked above.
            if settings is None or name in inline:
                continue
            from_file[name] = settings[-1]
            if id(settings) in seen:
                continue
            seen.add(id(settings))  # the plans hold every history until the expansion is made
            if (problem := spec.problem(settings[-1].value)) is not None:
                raise SpecError(_refused_value(plan, node, name, problem), Location(settings[-1].source))
        _check_together(plan, node, specs, from_file)


# Which of the values a rule reads its refusal is placed at: the one given last in precedence
# (inline in the launch file over --set over the robot's over the defaults' over the template's).
_PRECEDENCE = {layer: rank for rank, layer in enumerate((*LAYERS, INLINE_LAYER))}


def _check_together(
    plan: RobotPlan, node: NodeOutline, specs: dict[str, ParamSpec], from_file: dict[str, Setting]
) -> None:
    """Refuse the values a node gets (from the parameter file, `from_file`, or inline; each of
    them of its declared type and in range, checked before) when its rules refuse them together,
    with its defaults for those not given, as the node has them when it checks.  Placed at the
    value given last in precedence of those the refusing rule reads.  A rule that reads a value
    only the agent's computer can tell is left to the node."""
    given = dict(from_file)
    unknown = set()
    for name, setting in plan.inline.get(node.name, {}).items():
        if name in specs:
            given[name] = Setting(setting.value, INLINE_LAYER, str(plan.launch_place(setting.where)))
            if not setting.known:
                unknown.add(name)
    values = {name: spec.coerce(given[name].value) if name in given else spec.default for name, spec in specs.items()}
    for rule in rules(node.package, node.executable):
        read = [given[name] for name in rule.names if name in given]
        # Of the node's defaults alone (which pass its rules: tests/nodes), or told on the agent.
        if not read or unknown.intersection(rule.names):
            continue
        if (problem := rule.problem(values)) is not None:
            blamed = max(read, key=lambda setting: _PRECEDENCE[setting.layer])
            raise SpecError(_refused_value(plan, node, rule.names[0], problem), Location(blamed.source))


def _refused_value(plan: RobotPlan, node: NodeOutline, name: str, problem: str) -> str:
    return f"robot {plan.name}: {node.name}.{name} {problem} ({node.package} {node.executable} refuses it at start)"


def _misnamed_defaults(templates: TemplateSet, robots: list[RobotPlan]) -> list[str]:
    """A warning for each template the robots use whose parameter defaults look misnamed: without
    them its nodes get no defaults and the spec's parameter names are checked against nothing."""
    warnings = []
    for template in sorted({plan.template for plan in robots}):
        if found := templates.misnamed_defaults(template):
            warnings.append(
                f"{found}: not read as template {template}'s parameter defaults, which must be named "
                f"{template}{PARAMS_SUFFIX}; it has none"
            )
    return warnings


def _sim_time_without_world(spec: FleetSpec, robots: list[RobotPlan]) -> list[str]:
    """A warning when robots follow /clock that no world of theirs publishes: in a fleet without
    a world their nodes' time stands still at 0 (timers never fire) until something else publishes
    /clock, a simulator of the user's own, say; a real robot (`simulated: false`) of a fleet with
    a world would run on the simulation's time.  Real robots want `use_sim_time: false`."""
    # What the nodes start with, not the fleet's setting: a template of the user's own may give
    # its nodes wall time whatever `ros.use_sim_time` says, or no use_sim_time at all.
    on_sim_time = [plan.name for plan in robots if (spec.world is None or not plan.simulated) and plan.on_sim_time]
    if not on_sim_time:
        return []
    shown = ", ".join(on_sim_time[:3]) + (f" and {len(on_sim_time) - 3} more" if len(on_sim_time) > 3 else "")
    default = "" if "use_sim_time" in spec.ros.model_fields_set else ", the default"
    where = _spec_location(spec, ("ros", "use_sim_time"))
    if spec.world is None:
        return [
            f"{where}: robots {shown} run on sim time (use_sim_time true{default}) "
            "but the fleet has no world to publish /clock: their nodes' time stands still until something else "
            "does; set `ros: {use_sim_time: false}` for real robots, or add a `world`"
        ]
    return [
        f"{where}: robots {shown} are real (simulated: false) but run on the world's sim time "
        f"(use_sim_time true{default}): give each `launch_args: {{use_sim_time: false}}`"
    ]


def _unused_for_inline(plan: RobotPlan) -> dict[tuple[str, str], str]:
    """(node, name) -> a warning, for each value the spec or `--set` gives a parameter that the
    launch file gives inline after the parameter file: rcl applies the later file, so the node
    never gets the spec's value (the template's own defaults are its author's to keep apart)."""
    warnings = {}
    for node, settings in plan.inline.items():
        if node in plan.without_file:  # none of its file reaches it: one warning for the node
            continue
        for name, inline in settings.items():
            history = plan.parameters.history.get((node, name))
            if history and history[-1].layer != "template":
                place = plan.launch_place(inline.where)
                warnings[(node, name)] = (
                    f"{history[-1].source}: {node}.{name} is not used: the launch file gives it inline after the "
                    f"parameter file ({place}: {value_text(inline.shown)}), and that value wins; "
                    "set it through the template's launch arguments, if it has one"
                )
    return warnings


def _unread_for_lack_of_file(plan: RobotPlan) -> dict[str, str]:
    """node -> a warning, for each node the launch file starts without the robot's parameter file
    while fleet writes parameters for it there: launch gives a node only the files its `param`
    list names, so it gets none of them (the template's defaults included) and keeps its own."""
    warnings = {}
    for node, where in plan.without_file.items():
        names = sorted(name for (of, name) in plan.parameters.history if of == node)
        if names:
            shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
            warnings[node] = (
                f"{plan.launch_place(where)}: node {node} is started without the robot's parameter file, so none "
                f"of its parameters there reach it ({shown}); add `- from: {{{{ params_file }}}}` to its param "
                f"list in template {plan.template}"
            )
    return warnings


def _once(warnings: list[str]) -> str:
    """The first of the warnings about one name, saying how many other places set it."""
    others = len(set(warnings)) - 1
    return warnings[0] + (f" (and {others} more place{'s' if others > 1 else ''})" if others else "")


def _plan_robot(
    spec: FleetSpec,
    index: int,
    robot: Robot,
    templates: TemplateSet,
    renderer: LaunchRenderer,
    shared_layers: SharedLayers,
) -> RobotPlan:
    template = robot.template or spec.defaults.template
    namespace = robot.namespace or f"/{robot.name}"
    arguments = {**spec.defaults.launch_args, **robot.launch_args}
    model = _model_of(spec, robot)
    pose = robot.pose.model_dump()
    context = {
        "robot": {
            "name": robot.name,
            "namespace": namespace,
            "agent": robot.agent or spec.defaults.agent,
            "model": model.model_dump(),
            "pose": pose,
        },
        "fleet": {"name": spec.fleet, "domain_id": spec.ros.domain_id, "use_sim_time": spec.ros.use_sim_time},
        "params_file": params_file_reference(robot.name),
    }
    if templates.find(template) is None:
        path: DocPath = ("robots", index, "template") if robot.template else ("defaults", "template")
        raise templates.not_found(template, _spec_location(spec, path))
    rendered = renderer.render(template, context, arguments, Location(spec.source_file))
    shape = rendered.outline
    # A value reaches a robot only through the template's arg() (it becomes the default the
    # rendered file declares; agents pass no launch arguments), so only those take one.
    unknown = sorted(set(arguments) - set(rendered.argument_defaults))
    if unknown:
        in_robot = unknown[0] in robot.launch_args
        path = ("robots", index, "launch_args", unknown[0]) if in_robot else ("defaults", "launch_args", unknown[0])
        refusal = (
            f"template {template!r} declares launch argument {unknown[0]!r} without arg(), so no value reaches it "
            f'(write its default as {{{{ arg("{unknown[0]}", ...) }}}})'
            if unknown[0] in shape.arguments
            else f"template {template!r} declares no launch argument {unknown[0]!r} "
            f"(arguments: {', '.join(rendered.argument_defaults) or 'none'})"
        )
        raise SpecError(refusal, _spec_location(spec, path))
    for name, value in arguments.items():
        if problem := argument_problem(value, rendered.argument_defaults.get(name)):
            path = (
                ("robots", index, "launch_args", name)
                if name in robot.launch_args
                else ("defaults", "launch_args", name)
            )
            raise SpecError(f"launch argument {name} {problem}", _spec_location(spec, path))
    if rendered.problem is not None:  # what the agent's check would refuse (robot/robot.launch.yaml:LINE:COL)
        raise rendered.problem
    for shaped in shape.nodes:
        if problem := node_name_problem(shaped.fqn):
            at: DocPath = ("robots", index, "namespace") if robot.namespace else ("robots", index, "name")
            raise SpecError(f"robot {robot.name}: {problem}", _spec_location(spec, at))
    node_names = {node.name for node in shape.nodes}
    layers = _shared_layers(spec, templates, template, frozenset(node_names), shared_layers).copy()
    started = {node.fqn for node in shape.nodes}
    if layers.hosted and params_file_reference(robot.name) not in rendered.text:
        raise TemplateError(
            f"parameter defaults for hosted nodes ({', '.join(layers.hosted)}), but no node of template "
            f"{template!r} is given the robot's parameter file ({{{{ params_file }}}}): no process would read them",
            Location(rendered.template_file),
        )
    for hosted in layers.hosted:
        fqn = hosted_fqn(namespace, hosted)
        if fqn in started or (problem := node_name_problem(fqn)):
            at = ("robots", index, "namespace") if robot.namespace else ("robots", index, "name")
            why = f"the template's launch file starts a node {fqn} too" if fqn in started else problem
            raise SpecError(f"robot {robot.name}: hosted node {hosted}: {why}", _spec_location(spec, at))
    for node, values in robot.parameters.items():
        if node not in node_names and node not in layers.hosted:
            raise SpecError(
                f"robot {robot.name}: {_no_node(template, node, node_names, layers.hosted)}",
                _spec_location(spec, ("robots", index, "parameters", node)),
            )
        layers.add(node, values, "robot", _spec_place(spec, "robots", index, "parameters", node))
    return RobotPlan(
        name=robot.name,
        namespace=namespace,
        agent=robot.agent or spec.defaults.agent,
        template=template,
        isolation=robot.isolation or spec.defaults.isolation,
        model=model,
        pose=pose,
        simulated=robot.simulated,
        outline=shape,
        parameters=layers,
        launch_args={k: str(v) for k, v in arguments.items()},
        launch_text=rendered.text,
        launch_python=rendered.python,
        shared=rendered.shared,
        inline=rendered.inline,
        without_file=rendered.without_file,
    )


def _shared_layers(
    spec: FleetSpec, templates: TemplateSet, template: str, node_names: frozenset[str], cache: SharedLayers
) -> ParameterLayers:
    """The template's defaults and the spec's defaults: the same for every robot of a template,
    so merged once per template and node set, and copied per robot."""
    key = (template, node_names)
    if key in cache:
        return cache[key]
    defaults, defaults_source = _template_defaults(templates, template)
    layers = ParameterLayers()
    layers.hosted = tuple(node for node in defaults if "/" in node)
    for node, values in defaults.items():
        assert defaults_source is not None  # there are defaults only when read from a file
        if node not in node_names and node not in layers.hosted:
            raise TemplateError(
                f"defaults for node {node!r}, which template {template!r} does not start"
                f"{did_you_mean(node, node_names)} (nodes: {', '.join(sorted(node_names))})",
                defaults_source.locate((node,), key=True),
            )
        layers.add(node, values, "template", _file_place(defaults_source, node))
    for node, values in spec.defaults.parameters.items():
        if node in node_names or node in layers.hosted:
            layers.add(node, values, "defaults", _spec_place(spec, "defaults", "parameters", node))
    layers.template_names = {node: frozenset(flatten(values)) for node, values in defaults.items()}
    cache[key] = layers
    return layers


def hosted_fqn(namespace: str, hosted: str) -> str:
    """The full name of a node hosted inside another's process, from its name relative to the
    robot's namespace: /robot1 and local_costmap/local_costmap -> /robot1/local_costmap/local_costmap."""
    return f"{namespace.rstrip('/')}/{hosted}"


def _no_node(template: str, node: str, started: set[str], hosted: tuple[str, ...]) -> str:
    if "/" in node:
        return (
            f"template {template!r} hosts no node {node!r} (hosted nodes, given in its parameter defaults: "
            f"{', '.join(hosted) or 'none'})"
        )
    return f"template {template!r} starts no node {node!r} (nodes: {', '.join(sorted(started))})"


def _spec_place(spec: FleetSpec, *prefix: Any) -> Callable[[DocPath], str]:
    """Where a parameter below `prefix` is written in the spec, from its key path there."""
    return lambda key: spec.where(*prefix, *key)


def _file_place(source: SourceMap, *prefix: Any) -> Callable[[DocPath], str]:
    """Where a parameter below `prefix` is written in a YAML file, from its key path there."""
    return lambda key: str(source.locate((*prefix, *key)))


def _spec_location(spec: FleetSpec, path: DocPath) -> Location:
    if spec._source_map is None:
        return Location(spec.source_file)
    return spec._source_map.locate(path, key=True)


def _template_defaults(templates: TemplateSet, template: str) -> tuple[dict[str, dict[str, Any]], SourceMap | None]:
    path = templates.defaults_file(template)
    if path is None:
        return {}, None
    # Its top-level keys are nodes; everything below is a node's parameters, typed as rcl types them.
    data, source = load_yaml(read_input(path, "template parameter defaults"), path, ((None,),))
    if data is None:
        return {}, source
    if not isinstance(data, dict):
        raise TemplateError("parameter defaults must map node names to parameter mappings", Location(path, 1))
    for node, values in data.items():
        if not isinstance(values, dict):  # at the node's value, or its key when it has none (`battery:`)
            got = "nothing" if values is None else f"a {type(values).__name__}"
            raise TemplateError(
                f"parameter defaults of node {node}: expected a mapping of parameters (write {{}} for none), got {got}",
                source.locate((node,), key=values is None),
            )
    from fleet.spec.load import check_parameters

    check_parameters(data, (), source)
    return data, source


def _apply_overrides(spec: FleetSpec, robots: list[RobotPlan], overrides: list[Override]) -> None:
    by_name = {plan.name: plan for plan in robots}
    for override in overrides:
        where = Location(f"--set {override.text}")
        plan = by_name.get(override.robot)
        if plan is None:
            hint = did_you_mean(override.robot, by_name)
            raise SpecError(
                f"no robot {override.robot!r} in {spec.source_file}{hint} (robots: {', '.join(by_name)})", where
            )
        nodes = sorted({node.name for node in plan.outline.nodes}) + list(plan.parameters.hosted)
        if override.node not in nodes:
            hint = did_you_mean(override.node, nodes)
            raise SpecError(f"robot {plan.name} has no node {override.node!r}{hint} (nodes: {', '.join(nodes)})", where)
        group = plan.parameters.group_of(override.node, override.parameter)
        if group:
            # Written as one value, the group would vanish from the file: refused, whatever the
            # value, rather than left to the check of every layer, which says less.
            count = f"{len(group)} parameter{'s' * (len(group) > 1)}"
            raise SpecError(
                f"{override.node}.{override.parameter} is a parameter in the --set layer and the namespace of "
                f"{override.node}.{group[0]} (a group of {count}): set them one by one "
                f"(--set {plan.name}.{override.node}.{group[0]}=...)",
                where,
            )
        plan.parameters.set(override.node, override.parameter, override.value, "--set", f"--set {override.text}")


def _check_default_nodes(spec: FleetSpec, robots: list[RobotPlan]) -> None:
    all_nodes = {node.name for plan in robots for node in plan.outline.nodes}
    all_nodes |= {hosted for plan in robots for hosted in plan.parameters.hosted}
    for node in spec.defaults.parameters:
        if node not in all_nodes:
            raise SpecError(
                f"defaults.parameters: no robot's template starts a node {node!r} "
                f"(nodes: {', '.join(sorted(all_nodes))})",
                _spec_location(spec, ("defaults", "parameters", node)),
            )


def _model_of(spec: FleetSpec, robot: Robot) -> Model:
    changes = robot.model.model_dump(exclude_none=True)
    return spec.defaults.model.model_copy(update=changes) if changes else spec.defaults.model


def _robot_bundle(spec: FleetSpec, plan: RobotPlan, sections: dict[DocPath, str] | None = None) -> Bundle:
    files = {
        f"{plan.name}{LAUNCH_SUFFIX}": plan.launch_text,
        f"{plan.name}{PYTHON_LAUNCH_SUFFIX}": plan.launch_python,
        f"{plan.name}{PARAMS_SUFFIX}": params_file_text(spec, plan, sections),
    }
    return Bundle(
        name=plan.name,
        kind="robot",
        agent=plan.agent,
        entry=f"{plan.name}{LAUNCH_SUFFIX}",
        files=files,
        # The agent reports it with the robot's state: the world does not judge a real robot.
        options={**isolation_options(spec, plan.isolation), **({} if plan.simulated else {SIMULATED_OPTION: False})},
    )


def isolation_options(spec: FleetSpec, isolation: str) -> dict[str, str]:
    """What the agent needs to know to place the robot's processes."""
    if isolation == "agent":
        return {"isolation": isolation, "group_size": str(spec.defaults.group_size)}
    return {"isolation": isolation}


def params_file_text(spec: FleetSpec, plan: RobotPlan, sections: dict[DocPath, str] | None = None) -> str:
    """One fully-qualified section per node: /robot1/controller: {ros__parameters: {...}}.

    `sections` keeps the text of sections robots share (a node whose parameters a robot did not
    change is its template's and the spec's defaults): written once, not once per robot."""
    sections = {} if sections is None else sections
    layers = plan.parameters
    done = set()
    text = []
    for node in plan.outline.nodes:
        if node.fqn in done:
            continue
        done.add(node.fqn)
        text.append(f"{yaml_emit.mapping_key(node.fqn)}:\n{_section_body(layers, node.name, sections)}")
    for hosted in layers.hosted:
        # Read by the process that hosts the node: launch gives --params-file to a whole process,
        # each of whose nodes takes the section of its own full name.
        fqn = hosted_fqn(plan.namespace, hosted)
        text.append(f"{yaml_emit.mapping_key(fqn)}:\n{_section_body(layers, hosted, sections)}")
    header = (
        f"# Parameters of robot {plan.name} in fleet {spec.fleet}, generated by fleet.\n"
        f"# Layers, lowest first: template {plan.template} < spec defaults < robot < --set.\n"
        f"# See where a value comes from: fleet render SPEC --explain {plan.name}.NODE.PARAMETER\n"
    )
    return header + "".join(text)


def _section_body(layers: ParameterLayers, node: str, sections: dict[DocPath, str]) -> str:
    key = (id(layers.origin), node) if layers.same_as_origin(node) else None
    body = sections.get(key) if key is not None else None
    if body is None:
        body = yaml_emit.emit({"ros__parameters": unflatten(layers.effective_of(node))}, indent=1)
        if key is not None:
            sections[key] = body
    return body


def world_description(spec: FleetSpec) -> dict[str, Any]:
    """The data of world.yaml (schema in docs/architecture.md)."""
    assert spec.world is not None
    world = spec.world
    robots = []
    for robot in spec.robots:
        if not robot.simulated:
            continue
        lidar = robot.lidar or spec.defaults.lidar
        robots.append(
            {
                "name": robot.name,
                "namespace": robot.namespace or f"/{robot.name}",
                "model": _model_of(spec, robot).model_dump(),
                "pose": robot.pose.model_dump(),
                "lidar": lidar.model_dump(),
                "odom_rate": world.odom_rate,
                "cmd_timeout": world.cmd_timeout,
                "ground_truth": True,
            }
        )
    obstacles = []
    for obstacle in world.obstacles:
        entry = {"name": obstacle.name, "type": obstacle.type, "position": list(obstacle.position), "yaw": obstacle.yaw}
        if obstacle.type == "cylinder":
            entry.update(radius=obstacle.radius, height=obstacle.height)
        else:
            assert obstacle.size is not None  # Obstacle's validator: boxes and walls have a size
            entry["size"] = list(obstacle.size)
        obstacles.append(entry)
    return {
        "fleet": spec.fleet,
        "physics_rate": world.physics_rate,
        "real_time": world.real_time,
        "clock_rate": world.clock_rate if world.clock_rate is not None else default_clock_rate(world.physics_rate),
        "obstacles": obstacles,
        "robots": robots,
    }


def _world_bundle(spec: FleetSpec, templates: TemplateSet) -> Bundle:
    context = {"fleet": {"name": spec.fleet, "domain_id": spec.ros.domain_id, "use_sim_time": spec.ros.use_sim_time}}
    rendered = templates.render(WORLD_TEMPLATE, context, {}, Location(spec.source_file))
    launch, source = parse_rendered(rendered.text, rendered.template_file, WORLD_UNIT)
    outline(launch, source, rendered.template_file)
    header = (
        f"# The shared world of fleet {spec.fleet}, generated by fleet. Robots join and leave as this file changes.\n"
    )
    description = world_description(spec)
    files = {
        f"{WORLD_UNIT}{LAUNCH_SUFFIX}": rendered.text,
        f"{WORLD_UNIT}{PYTHON_LAUNCH_SUFFIX}": python_source(
            launch, f"The shared world of fleet {spec.fleet}, generated by fleet.", rendered.template_file
        ),
        WORLD_DESCRIPTION: header + yaml_emit.emit(description),
    }
    assert spec.world is not None
    agent = spec.world.agent or spec.defaults.agent
    bundle = Bundle(
        name=WORLD_UNIT,
        kind="world",
        agent=agent,
        entry=f"{WORLD_UNIT}{LAUNCH_SUFFIX}",
        files=files,
        options={"isolation": "process"},
        hot_files=frozenset({WORLD_DESCRIPTION}),
    )
    _check_files(spec, bundle)
    _check_world(spec, description)
    return bundle


def _check_world(spec: FleetSpec, description: dict[str, Any]) -> None:
    """Refuse what the world would refuse when it loads this description: its own checks of
    world.yaml and its spawn check, reported at the places in the spec the values come from."""
    simulated = [index for index, robot in enumerate(spec.robots) if robot.simulated]
    world = world_spec(description, _WorldPlaces(spec, simulated))
    problem = spawn_problem(world)
    if problem is not None:
        index, why = problem
        raise SpecError(
            f"the world would not spawn it: {why}", _spec_location(spec, ("robots", simulated[index], "pose"))
        )


class _WorldPlaces(SourceMap):
    """Where world.yaml's values are written in the spec: `world.yaml robots[k]` is the k-th
    simulated robot, its obstacles and settings are the spec's `world`; what world_description
    gives a robot from elsewhere is placed there (its odom_rate: the spec's `world.odom_rate`;
    a lidar or model field the robot does not write: `defaults`)."""

    def __init__(self, spec: FleetSpec, simulated: list[int]):
        super().__init__(spec.source_file)
        self.spec = spec
        self.simulated = simulated

    def locate(self, path: DocPath, key: bool = False) -> Location:
        if path[:1] == ("robots",) and len(path) > 1:
            index, field = self.simulated[path[1]], path[2:]
            spec_path: DocPath = ("robots", index, *field)
            if field[:1] in (("odom_rate",), ("cmd_timeout",)):
                spec_path = ("world", *field)
            elif (
                (field[:1] == ("model",) or (field[:1] == ("lidar",) and self.spec.robots[index].lidar is None))
                and not self._written(spec_path)
                and self._written(("defaults", *field))
            ):
                spec_path = ("defaults", *field)
        elif path[:1] == ("fleet",):
            spec_path = path
        else:
            spec_path = ("world", *path)
        source = self.spec._source_map
        return source.locate(spec_path, key=key) if source is not None else Location(self.spec.source_file)

    def _written(self, path: DocPath) -> bool:
        """Whether the spec writes a value at `path`."""
        source = self.spec._source_map
        if source is None:
            return False
        source.locate(())  # the positions are read when first asked for
        return tuple(path) in source.positions


def _check_files(spec: FleetSpec, bundle: Bundle) -> None:
    """An agent refuses a bundle with too many or too large files: refuse it here first."""
    if problem := files_problem(bundle.files):
        if bundle.kind == "world":
            raise SpecError(
                f"an agent would refuse the world's files: {problem} (simulate fewer robots in one world)",
                _spec_location(spec, ("world",)),
            )
        raise SpecError(
            f"an agent would refuse robot {bundle.name}'s files: {problem}",
            _spec_location(spec, ("robots", _robot_index(spec, bundle.name))),
        )


def _check_deliverable(spec: FleetSpec, bundles: list[Bundle], routes: dict[str, BridgeRoutes]) -> None:
    """Every bundle, and every agent's share of them with its bridge's routes, is small enough
    for the agents (fleet.wire.limits, fleet.wire.topics)."""
    by_agent: dict[str, list[Bundle]] = {}
    for bundle in bundles:
        if bundle.kind == "robot":
            _check_files(spec, bundle)
        by_agent.setdefault(bundle.agent, []).append(bundle)
    for agent, group in by_agent.items():
        route_bytes = 0
        if agent_routes := routes.get(agent):
            _check_route_count(spec, agent, agent_routes)
            route_bytes = len(agent_routes.model_dump_json())
        size = apply_size_bound(bundle.json_size for bundle in group) + route_bytes
        if size > MAX_MESSAGE_BYTES:
            raise SpecError(
                f"agent {agent}'s {len(group)} units make a deploy message of up to {size / 2**20:.1f} MiB; "
                f"an agent accepts {MAX_MESSAGE_BYTES / 2**20:.0f} MiB: spread the robots over more agents",
                _spec_location(spec, ("agents", agent)),
            )


def _check_route_count(spec: FleetSpec, agent: str, routes: BridgeRoutes) -> None:
    from fleet.wire.protocol import MAX_ROUTES

    if (count := max(len(routes.exports), len(routes.imports))) > MAX_ROUTES:
        raise SpecError(
            f"agent {agent}'s Zenoh bridge would carry {count} topics one way; an agent carries at most "
            f"{MAX_ROUTES}: put more robots on the world's agent, or use transport dds",
            _spec_location(spec, ("ros", "transport")),
        )


def _bridge_routes(spec: FleetSpec, bundles: list[Bundle], robots: list[RobotPlan]) -> dict[str, BridgeRoutes]:
    """The topics each agent's bridge will carry (the `zenoh` transport sends them with the deploy)."""
    if spec.ros.transport != "zenoh":
        return {}
    # The protocol's models: only for fleets that bridge.
    from fleet.wire.protocol import TopicRoute
    from fleet.wire.topics import SharedRoute, bridge_routes

    world_agent = next((bundle.agent for bundle in bundles if bundle.kind == "world"), None)
    shared = [
        SharedRoute(
            robot.agent,
            TopicRoute(**topic.route_fields),
            topic.publishes,
            topic.subscribes,
        )
        for robot in robots
        for topic in robot.shared
    ]
    # The world's topics cross only for robots it hosts: a real robot's odom comes from its own
    # driver on its own computer, and its cmd_vel has no business on the world's.
    hosted = [(robot.name, robot.namespace, robot.agent) for robot in robots if robot.simulated]
    return bridge_routes(world_agent, hosted, shared)


def _check_shared(spec: FleetSpec, robots: list[RobotPlan], templates: TemplateSet) -> None:
    """A shared topic has one type and one QoS fleet-wide, and is not one the fleet carries
    already (the world's topics for each robot and /clock)."""
    if not any(plan.shared for plan in robots):
        return
    first: dict[str, tuple[RobotPlan, SharedTopic]] = {}
    world_topics: set[str] = set()
    if spec.world is not None:
        from fleet.wire.topics import world_topic_names

        simulated = {robot.name for robot in spec.robots if robot.simulated}
        world_topics = world_topic_names(plan.namespace for plan in robots if plan.name in simulated)
    for plan in robots:
        for topic in plan.shared:
            where = Location(templates.find(plan.template), topic.line)
            if topic.name in world_topics:
                raise TemplateError(
                    f"robot {plan.name} shares {topic.name}, which the world's topics already carry "
                    "(each robot's odom, scan, ground_truth, cmd_vel, battery and /clock)",
                    where,
                )
            known = first.setdefault(topic.name, (plan, topic))
            if problem := conflict(known[1], topic):
                raise TemplateError(
                    f"shared topic {topic.name}: robots {known[0].name} and {plan.name} declare it with {problem}: "
                    "a shared topic has one type and one QoS in the whole fleet",
                    where,
                )


def _check_units_per_agent(spec: FleetSpec) -> None:
    """An agent runs at most MAX_BUNDLES units: known before anything is expanded."""
    units: dict[str, int] = {}
    for robot in spec.robots:
        agent = robot.agent or spec.defaults.agent
        units[agent] = units.get(agent, 0) + 1
    if spec.world is not None:
        agent = spec.world.agent or spec.defaults.agent
        units[agent] = units.get(agent, 0) + 1
    for agent, count in units.items():
        if count > MAX_BUNDLES:
            raise SpecError(
                f"agent {agent} would run {count} units; an agent runs at most {MAX_BUNDLES}: "
                "spread the robots over more agents",
                _spec_location(spec, ("agents", agent)),
            )


def _robot_index(spec: FleetSpec, name: str) -> int:
    return next(index for index, robot in enumerate(spec.robots) if robot.name == name)
