"""The shortcuts that make expansion linear and fast never change what a robot gets: each robot's
files are what rendering its template and writing its parameters alone would give."""

from __future__ import annotations

import textwrap

import pytest

from fleet.errors import Location, TemplateError
from fleet.expand import expand_fleet
from fleet.expand.expansion import template_set_for
from fleet.expand.rendered_launch import params_file_reference
from fleet.spec import parse_spec

CUSTOM = """\
launch:
- arg: {name: speed, default: {{ arg("speed", 1.5) }}}
- group:
  - push_ros_namespace: {namespace: {{ robot.namespace }}}
{% if robot.name == "r2" %}
  - node: {pkg: fleet_nodes, exec: battery, name: battery}
{% endif %}
  - node: {pkg: fleet_nodes, exec: controller, name: controller, args: {{ "x=" ~ robot.pose.x }}}
"""


@pytest.fixture
def spec(tmp_path):
    templates = tmp_path / "templates"
    templates.mkdir()
    (templates / "custom.launch.yaml.j2").write_text(CUSTOM)
    (templates / "named.launch.yaml.j2").write_text(
        "launch:\n- group:\n  - push_ros_namespace: {namespace: {{ robot.namespace }}}\n"
        "  - node: {pkg: fleet_nodes, exec: controller, name: {{ robot.name }}}\n"
    )
    text = textwrap.dedent(
        f"""\
        fleet: demo
        templates: {templates}
        defaults:
          parameters: {{controller: {{max_speed: 0.7}}}}
        robots:
          - {{name: r1, template: custom}}
          - {{name: r2, template: custom, pose: {{x: 3.0}}}}
          - {{name: r3, template: custom, pose: {{x: 6.0}}, launch_args: {{speed: 2}}}}
          - {{name: r4, namespace: /site/r4}}
          - {{name: r5, parameters: {{controller: {{max_speed: 0.9}}}}}}
          - {{name: r6}}
          - {{name: r7, template: named, namespace: /a/b}}
        """
    )
    return parse_spec(text, str(tmp_path / "fleet.yaml"))


def test_only_templates_that_print_the_identity_skip_rendering(spec):
    templates = template_set_for(spec)
    assert templates.identity_only("diff_drive") and templates.identity_only("named")
    assert not templates.identity_only("custom")


def test_every_robot_gets_its_own_rendering(spec):
    expansion = expand_fleet(spec)
    templates = template_set_for(spec)
    for index, robot in enumerate(spec.robots):
        plan = expansion.robots[index]
        namespace = robot.namespace or f"/{robot.name}"
        context = {
            "robot": {
                "name": robot.name,
                "namespace": namespace,
                "agent": "local",
                "model": plan.model.model_dump(),
                "pose": robot.pose.model_dump(),
            },
            "fleet": {"name": "demo", "domain_id": 0, "use_sim_time": True},
            "params_file": params_file_reference(robot.name),
        }
        alone = templates.render(plan.template, context, dict(robot.launch_args), Location("x"))
        assert plan.launch_text == alone.text, robot.name
        assert [node.fqn for node in plan.outline.nodes] == [f"{namespace}/{node.name}" for node in plan.outline.nodes]
    r1, r2, r3, r7 = (plan_of(expansion, name) for name in ("r1", "r2", "r3", "r7"))
    assert [node.name for node in r2.outline.nodes] == ["battery", "controller"]
    assert [node.name for node in r1.outline.nodes] == ["controller"]
    assert "x=6.0" in r3.launch_text and 'default: "2"' in r3.launch_text
    assert [node.fqn for node in r7.outline.nodes] == ["/a/b/r7"]


def test_shared_parameter_sections_are_each_robots_own(spec):
    """Sections shared between robots (written once) read as each robot's own would."""
    import yaml

    expansion = expand_fleet(spec, ["r6.safety.safety_distance=0.9"])
    for name, max_speed, safety_distance in (("r4", 0.7, 0.4), ("r5", 0.9, 0.4), ("r6", 0.7, 0.9)):
        bundle = expansion.bundle(name)
        assert bundle is not None
        namespace = plan_of(expansion, name).namespace
        params = yaml.safe_load(bundle.files[f"{name}.params.yaml"])
        assert set(params) == {f"{namespace}/controller", f"{namespace}/battery", f"{namespace}/safety"}
        assert params[f"{namespace}/controller"]["ros__parameters"]["max_speed"] == max_speed
        assert params[f"{namespace}/safety"]["ros__parameters"]["safety_distance"] == safety_distance


def test_digests_are_those_of_the_files_themselves(spec):
    """Bundle JSON made once for the digest and the message size is the digest of the files
    (what agents compare to decide on restarts)."""
    import hashlib
    import json

    for bundle in expand_fleet(spec).bundles:
        cold = {name: text for name, text in sorted(bundle.files.items()) if name not in bundle.hot_files}
        payload = {"entry": bundle.entry, "options": dict(sorted(bundle.options.items())), "files": cold}
        assert bundle.digest == hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()
        assert bundle.json_size >= sum(len(json.dumps(text)) for text in bundle.files.values())


def plan_of(expansion, name: str):
    plan = expansion.robot(name)
    assert plan is not None, name
    return plan


LOOKUP = """\
{% set ids = {"r1": 1, "r2": 2} %}
launch:
- arg: {name: robot_id, default: {{ ids[robot.name]|string }}}
- group:
  - push_ros_namespace: {namespace: {{ robot.namespace }}}
"""


def lookup_spec(tmp_path, template: str, robots: str):
    templates = tmp_path / "lookup"
    templates.mkdir(exist_ok=True)
    (templates / "t.launch.yaml.j2").write_text(template)
    text = f"fleet: demo\ntemplates: {templates}\ndefaults: {{template: t}}\nrobots: [{robots}]\n"
    return parse_spec(text, str(tmp_path / "fleet.yaml"))


@pytest.mark.parametrize(
    "template",
    [
        LOOKUP,
        "launch:\n{% if robot.name|length > 20 %}\n# {{ 1/0 }}\n{% endif %}\n"
        "- arg: {name: robot_id, default: {{ robot.name[1:] }}}\n",
    ],
)
def test_a_template_the_placeholder_robot_cannot_render_renders_for_each_robot(tmp_path, template):
    """The shortcut renders a template once for a placeholder robot, which is no robot of the spec:
    its failure was reported as the spec's error (a key no robot has, a branch no robot takes)."""
    expansion = expand_fleet(lookup_spec(tmp_path, template, "{name: r1}, {name: r2}"))
    for name, number in (("r1", 1), ("r2", 2)):
        assert f'- arg: {{name: robot_id, default: "{number}"}}' in plan_of(expansion, name).launch_text


def test_a_robot_the_template_cannot_render_is_refused_for_itself(tmp_path):
    with pytest.raises(TemplateError) as refused:
        expand_fleet(lookup_spec(tmp_path, LOOKUP, "{name: r1}, {name: r3}"))
    assert str(refused.value) == (
        f"{tmp_path / 'lookup' / 't.launch.yaml.j2'}:3: 'dict object' has no attribute 'r3' "
        "(available: fleet, params_file, robot, arg, share)"
    )
