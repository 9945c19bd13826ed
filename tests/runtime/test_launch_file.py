"""The YAML launch frontend subset: actions, scoping, conditions, substitutions, refusals."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from fleet.errors import LaunchFileError
from fleet.runtime.launch_file import check_launch_file, load_launch_file, parse_substitutions


@pytest.fixture
def demo(prefix):
    for exe in ("talker", "listener"):
        prefix.add(exe, "#!/bin/sh\nexec sleep 100\n")
    return prefix


@pytest.fixture
def load(demo, write_launch, tmp_path):
    """load(text, **launch_args) -> LaunchPlan, with the demo prefix and a params dir."""

    def run(text: str, env: dict | None = None, **launch_args: str):
        path = write_launch(text)
        return load_launch_file(path, launch_args, env=env or demo.env(), params_dir=tmp_path / "params")

    return run


def refused(load, text: str, *fragments: str, line: int | None = None, **launch_args):
    with pytest.raises(LaunchFileError) as caught:
        load(text, **launch_args)
    message = str(caught.value)
    assert "test.launch.yaml" in message
    for fragment in fragments:
        assert fragment in message, message
    if line is not None:
        assert caught.value.location is not None and caught.value.location.line == line, message
    return message


def params_of(node) -> list:
    """Contents of each --params-file, in order."""
    files = [node.cmd[i + 1] for i, arg in enumerate(node.cmd) if arg == "--params-file"]
    return [yaml.safe_load(Path(file).read_text()) for file in files]


# -- nodes and their command lines ----------------------------------------------------------


def test_minimal_node(load, demo):
    plan = load("""
        launch:
        - node: {pkg: demo, exec: talker}
    """)
    (node,) = plan.nodes
    assert node.cmd == [str(demo.root / "lib/demo/talker"), "--ros-args"]
    assert node.name is None and node.namespace is None and node.fqn is None
    assert node.process_name == "talker-1"
    assert node.output == "log" and node.respawn is False and node.respawn_delay == 0.0


def test_full_node_layout(load, demo, tmp_path):
    (tmp_path / "p.yaml").write_text("/ns/talker: {ros__parameters: {a: 1}}\n")
    plan = load(
        """
        launch:
        - node:
            pkg: demo
            exec: talker
            name: talker
            namespace: ns
            args: --flag 'two words' x$(var v)y
            ros_args: --log-level debug
            param:
            - {from: $(dirname)/p.yaml}
            - {name: rate, value: 2.5}
            remap:
            - {from: a, to: b}
            - {from: c, to: /d}
            respawn: 'true'
            respawn_delay: 1.5
            output: screen
    """,
        v="V",
    )
    (node,) = plan.nodes
    exe = str(demo.root / "lib/demo/talker")
    inline = node.cmd[node.cmd.index("-r", node.cmd.index(str(tmp_path / "p.yaml"))) - 1]
    assert node.cmd == [
        exe,
        "--flag",
        "two words",
        "xVy",
        "--ros-args",
        "--log-level",
        "debug",
        "--ros-args",
        "-r",
        "__node:=talker",
        "-r",
        "__ns:=/ns",
        "--params-file",
        str(tmp_path / "p.yaml"),
        "--params-file",
        inline,
        "-r",
        "a:=b",
        "-r",
        "c:=/d",
    ]
    assert Path(inline).name.startswith("launch_params_")
    assert Path(inline).parent == tmp_path / "params"
    assert params_of(node)[1] == {"/ns/talker": {"ros__parameters": {"rate": 2.5}}}
    assert node.respawn is True and node.respawn_delay == 1.5 and node.output == "screen"
    assert node.fqn == "/ns/talker"


def test_each_inline_param_is_its_own_file_in_order(load, tmp_path):
    (tmp_path / "a.yaml").write_text("/**: {ros__parameters: {x: 1}}\n")
    plan = load("""
        launch:
        - node:
            pkg: demo
            exec: talker
            name: t
            param:
            - {name: first, value: 1}
            - {from: $(dirname)/a.yaml}
            - {name: second, value: 'two'}
    """)
    assert params_of(plan.nodes[0]) == [
        {"/**": {"ros__parameters": {"first": 1}}},
        {"/**": {"ros__parameters": {"x": 1}}},
        {"/**": {"ros__parameters": {"second": "two"}}},
    ]


def test_inline_param_key_needs_name_and_namespace(load):
    plan = load("""
        launch:
        - node: {pkg: demo, exec: talker, name: t, param: [{name: p, value: 1}]}
        - node: {pkg: demo, exec: talker, namespace: ns, param: [{name: p, value: 1}]}
        - node: {pkg: demo, exec: talker, name: t, namespace: /ns, param: [{name: p, value: 1}]}
    """)
    keys = [next(iter(params_of(node)[0])) for node in plan.nodes]
    assert keys == ["/**", "/**", "/ns/t"]


def test_inline_param_values_are_typed_like_launch_ros(load):
    plan = load("""
        launch:
        - arg: {name: flag, default: 'true'}
        - node:
            pkg: demo
            exec: talker
            name: t
            namespace: n
            param:
            - {name: from_var, value: $(var flag)}
            - {name: int_text, value: '3'}
            - {name: float, value: 0.5}
            - {name: bool, value: false}
            - {name: text, value: hello}
            - {name: empty, value: ''}
            - {name: list, value: [1.0, 2.0]}
            - {name: list_text, value: '[1, 2]'}
            - {name: strings, value: [a, b]}
            - {name: dotted.name, value: 1}
    """)
    values = {}
    for content in params_of(plan.nodes[0]):
        values.update(content["/n/t"]["ros__parameters"])
    assert values == {
        "from_var": True,
        # Quoted text without a substitution stays a string under launch_ros (recorded in
        # tests/conformance/expected/19_param_quoted_values.launch.yaml.json).
        "int_text": "3",
        "float": 0.5,
        "bool": False,
        "text": "hello",
        "empty": "",
        "list": [1.0, 2.0],
        "list_text": "[1, 2]",
        "strings": ["a", "b"],
        "dotted.name": 1,
    }


def test_process_names_count_per_executable(load):
    plan = load("""
        launch:
        - node: {pkg: demo, exec: talker, name: a}
        - node: {pkg: demo, exec: listener, name: b}
        - node: {pkg: demo, exec: talker, name: c}
    """)
    # One counter for the whole launch, as launch numbers its processes (issue 11; recorded in
    # tests/conformance/expected/42_process_name_counter.launch.yaml.json).
    assert [node.process_name for node in plan.nodes] == ["talker-1", "listener-2", "talker-3"]


# -- namespaces -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("pushes", "own", "expected"),
    [
        ([], None, None),
        ([], "ns", "/ns"),
        ([], "/abs", "/abs"),
        (["robot1"], None, "/robot1"),
        (["robot1"], "sub", "/robot1/sub"),
        (["robot1"], "/abs", "/abs"),
        (["robot1", "inner"], None, "/robot1/inner"),
        (["robot1", "/reset"], None, "/reset"),
        (["/"], "x", "/x"),
        (["a/"], None, "/a"),
    ],
)
def test_namespace_rules(load, pushes, own, expected):
    lines = ["launch:", "- group:"]
    lines += [f"  - push_ros_namespace: {{namespace: '{ns}'}}" for ns in pushes]
    node = "  - node: {pkg: demo, exec: talker, name: t" + (f", namespace: '{own}'" if own else "")
    lines.append(node + "}")
    (plan_node,) = load("\n".join(lines) + "\n").nodes
    assert plan_node.namespace == expected
    if expected is None:
        assert not any(arg.startswith("__ns:=") for arg in plan_node.cmd)
    else:
        assert f"__ns:={expected}" in plan_node.cmd


def test_ros_arguments_a_node_would_not_start_with_are_refused(load):
    node = "launch:\n- node: {{pkg: demo, exec: talker, name: t, {0}}}\n"
    refused(load, node.format("ros_args: '--log-level bogus'"), "node t: --log-level 'bogus': give a level")
    refused(load, node.format("ros_args: '-r a-b:=c'"), "node t: from 'a-b' is not a ROS name")
    refused(load, node.format("args: 'x --ros-args --bogus'"), "node t: '--bogus' is not a ROS argument")


def test_invalid_namespace_and_name_are_refused(load):
    refused(load, "launch:\n- push_ros_namespace: {namespace: '1bad'}\n", "invalid namespace", line=2)
    refused(load, "launch:\n- node: {pkg: demo, exec: talker, name: 'a-b'}\n", "node 'a-b' is not a valid ROS name")
    refused(load, "launch:\n- node: {pkg: demo, exec: talker, namespace: 'a//b'}\n", "invalid namespace")
    # rcl cannot parse the remap rules `__node:=con__troller` and `__ns:=/site__a` launch_ros makes of them.
    refused(load, "launch:\n- node: {pkg: demo, exec: talker, name: con__troller}\n", "'__' is reserved")
    refused(load, "launch:\n- push_ros_namespace: {namespace: site__a}\n", "invalid namespace", line=2)


# -- launch configurations, scoping, conditions ----------------------------------------------


def test_args_defaults_overrides_and_required(load):
    text = """
        launch:
        - arg: {name: a, default: one, description: first}
        - arg: {name: b, default: $(var a)_two}
        - node: {pkg: demo, exec: talker, name: $(var b)_x}
    """
    plan = load(text)
    assert plan.nodes[0].name == "one_two_x"
    assert plan.arguments == {"a": "one", "b": "one_two"}
    plan = load(text, a="uno")
    assert plan.nodes[0].name == "uno_two_x"
    refused(load, "launch:\n- arg: {name: needed}\n", "'needed' is required", "needed:=VALUE", line=2)
    assert load("launch:\n- arg: {name: needed}\n", needed="x").arguments == {"needed": "x"}


def test_undeclared_launch_args_are_configurations(load):
    plan = load("launch:\n- node: {pkg: demo, exec: talker, name: $(var who)}\n", who="me")
    assert plan.nodes[0].name == "me"


def test_let_redefines_in_order(load):
    plan = load("""
        launch:
        - let: {name: x, value: first}
        - node: {pkg: demo, exec: talker, name: $(var x)}
        - let: {name: x, value: second}
        - node: {pkg: demo, exec: talker, name: $(var x)}
    """)
    assert [node.name for node in plan.nodes] == ["first", "second"]


def test_scoped_group_does_not_leak(load):
    plan = load("""
        launch:
        - let: {name: x, value: outer}
        - group:
          - let: {name: x, value: inner}
          - set_env: {name: FLEET_TEST_VAR, value: inside}
          - push_ros_namespace: {namespace: r1}
          - node: {pkg: demo, exec: talker, name: $(var x)}
        - node: {pkg: demo, exec: talker, name: $(var x)}
    """)
    inside, outside = plan.nodes
    assert (inside.name, inside.namespace, inside.env) == ("inner", "/r1", {"FLEET_TEST_VAR": "inside"})
    assert (outside.name, outside.namespace, outside.env) == ("outer", None, {})


def test_unscoped_group_leaks(load):
    plan = load("""
        launch:
        - group:
            scoped: false
            children:
            - let: {name: x, value: inner}
            - push_ros_namespace: {namespace: r1}
            - set_env: {name: V, value: '1'}
        - node: {pkg: demo, exec: talker, name: $(var x)}
    """)
    (node,) = plan.nodes
    assert (node.name, node.namespace, node.env) == ("inner", "/r1", {"V": "1"})


def test_group_inherits_outer_configuration(load):
    plan = load("""
        launch:
        - let: {name: x, value: outer}
        - group: {scoped: 'true', children: [{node: {pkg: demo, exec: talker, name: $(var x)}}]}
    """)
    assert plan.nodes[0].name == "outer"


@pytest.mark.parametrize(
    ("condition", "started"),
    [
        ("if: 'true'", True),
        ("if: 'TRUE'", True),
        ("if: '1'", True),
        ("if: 'false'", False),
        ("if: '0'", False),
        ("unless: 'true'", False),
        ("unless: 'False'", True),
    ],
)
def test_conditions(load, condition, started):
    plan = load(f"launch:\n- node: {{pkg: demo, exec: talker, {condition}}}\n")
    assert bool(plan.nodes) is started


def test_conditions_on_every_action(load):
    plan = load("""
        launch:
        - arg: {name: enabled, default: 'false'}
        - let: {name: x, value: a}
        - let: {name: x, value: b, if: $(var enabled)}
        - arg: {name: y, default: c, unless: $(var enabled)}
        - set_env: {name: E, value: '1', if: $(var enabled)}
        - push_ros_namespace: {namespace: skipped, if: $(var enabled)}
        - group:
            if: $(var enabled)
            children: [{node: {pkg: demo, exec: talker, name: never}}]
        - node: {pkg: demo, exec: talker, name: $(var x)_$(var y)}
    """)
    (node,) = plan.nodes
    assert (node.name, node.namespace, node.env) == ("a_c", None, {})
    plan = load(
        "launch:\n- arg: {name: enabled, default: 'false'}\n"
        "- node: {pkg: demo, exec: talker, name: n, if: $(var enabled)}\n",
        enabled="true",
    )
    assert [node.name for node in plan.nodes] == ["n"]


def test_bad_condition_value(load):
    refused(load, "launch:\n- node: {pkg: demo, exec: talker, if: 'yes'}\n", "'if' must be true/false/1/0", line=2)
    refused(load, "launch:\n- node: {pkg: demo, exec: talker, if: 'true', unless: 'true'}\n", "cannot both")


# -- substitutions --------------------------------------------------------------------------


def test_env_substitutions(load, demo):
    text = """
        launch:
        - set_env: {name: FROM_FILE, value: file}
        - node: {pkg: demo, exec: talker, name: $(env FLEET_X)_$(env MISSING fallback)_$(env FROM_FILE)}
    """
    plan = load(text, env=demo.env(FLEET_X="set"))
    assert plan.nodes[0].name == "set_fallback_file"
    refused(
        load,
        "launch:\n- node: {pkg: demo, exec: talker, name: $(env FLEET_SURELY_UNSET_VAR)}\n",
        "environment variable 'FLEET_SURELY_UNSET_VAR' is not set",
    )


def test_dirname_and_find_pkg_share(load, demo, tmp_path):
    plan = load("""
        launch:
        - node:
            pkg: demo
            exec: talker
            args: $(dirname) $(find-pkg-share demo)
    """)
    assert plan.nodes[0].cmd[1:3] == [str(tmp_path), str(demo.root / "share" / "demo")]
    refused(load, "launch:\n- let: {name: x, value: $(find-pkg-share nopkg)}\n", "package 'nopkg' not found", line=2)


def test_nested_and_quoted_substitutions(load):
    plan = load("""
        launch:
        - let: {name: which, value: inner}
        - let: {name: inner, value: found}
        - let: {name: spaced, value: "$(env 'NOT SET VAR' 'a default')"}
        - node: {pkg: demo, exec: talker, args: "$(var $(var which)) x", name: n}
    """)
    assert plan.nodes[0].cmd[1:3] == ["found", "x"]


def test_substitution_value_with_spaces_stays_one_argument(load):
    plan = load("""
        launch:
        - let: {name: v, value: 'a b'}
        - node: {pkg: demo, exec: talker, args: --x=$(var v) 'c d' e}
    """)
    assert plan.nodes[0].cmd[1:4] == ["--x=a b", "c d", "e"]


def test_parse_substitutions_structure():
    parts = parse_substitutions("pre $(var a)/$(env B 'c d') post")
    assert parts[0] == "pre " and parts[2] == "/" and parts[4] == " post"
    assert parts[1].kind == "var" and parts[3].kind == "env"


def test_undefined_var(load):
    refused(
        load,
        "launch:\n- node: {pkg: demo, exec: talker, name: $(var nope)}\n",
        "launch configuration 'nope' is not defined",
        line=2,
    )


def test_a_mistyped_launch_configuration_is_told_the_closest_defined_one(load):
    refused(
        load,
        "launch:\n- arg: {name: scan_topic, default: scan}\n"
        "- node: {pkg: demo, exec: talker, name: n, remap: [{from: scan, to: $(var scan_topc)}]}\n",
        "launch configuration 'scan_topc' is not defined (did you mean 'scan_topic'?)",
        line=3,
    )


# -- refusals -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "fragments", "line"),
    [
        ("launch:\n- include: {file: x.launch.yaml}\n", ["included launch file", "not found"], 2),
        ("launch:\n- shutdown: {}\n", ["action 'shutdown' needs the ros2 backend"], 2),
        (
            "launch:\n- node: {pkg: demo, exec: talker, launch-prefix: gdb}\n",
            ["attribute 'launch-prefix' of 'node' needs the ros2 backend"],
            2,
        ),
        (
            "launch:\n- node:\n    pkg: demo\n    exec: talker\n    bogus: [{name: a, value: b}]\n",
            ["unknown key 'bogus'"],
            5,
        ),
        ("launch:\n- arg: {name: a, choice: [{value: x}]}\n", ["argument 'a' is required"], 2),
        ("launch:\n- let: {name: a, value: $(command ls)}\n", ["'$(command)' is not run by the embedded runner"], 2),
        ("launch:\n- let: {name: a, value: $(var)}\n", ["'$(var)' takes 1..1 arguments"], 2),
        ("launch:\n- let: {name: a, value: '$(var a'}\n", ["unterminated"], 2),
        ("launch:\n- node: {exec: talker}\n", ["action 'node' needs 'pkg'"], 2),
        ("launch:\n- node: {pkg: demo}\n", ["action 'node' needs 'exec'"], 2),
        ("launch:\n- node: {pkg: demo, exec: nothere}\n", ["executable 'nothere' of package 'demo' not found"], 2),
        ("launch:\n- node: {pkg: nopkg, exec: talker}\n", ["package 'nopkg' not found", "searched"], 2),
        ("launch:\n- node: {pkg: demo, exec: talker, respawn: true}\n", ["must be a string"], 2),
        ("launch:\n- node: {pkg: demo, exec: talker, respawn_delay: 2}\n", ["non-negative float"], 2),
        ("launch:\n- node: {pkg: demo, exec: talker, output: own_log}\n", ["'output' must be"], 2),
        ("launch:\n- node: {pkg: demo, exec: talker, param: [{name: a}]}\n", ["'param' item"], 2),
        (
            "launch:\n- node: {pkg: demo, exec: talker, param: [{from: /no/such/file.yaml}]}\n",
            ["parameter file '/no/such/file.yaml' not found"],
            2,
        ),
        (
            "launch:\n- node: {pkg: demo, exec: talker, param: [{name: a, value: {b: 1}}]}\n",
            ["parameter value must be"],
            2,
        ),
        (
            "launch:\n- node: {pkg: demo, exec: talker, param: [{name: a, value: [1, 2.5]}]}\n",
            ["list items must all have one type"],
            2,
        ),
        (
            "launch:\n- let: {name: v, value: '{b: 1}'}\n"
            "- node: {pkg: demo, exec: talker, param: [{name: a, value: $(var v)}]}\n",
            ["is not a bool, int, float, string or list"],
            3,
        ),
        ("launch:\n- node: {pkg: demo, exec: talker, remap: [{from: a}]}\n", ["needs 'to'"], 2),
        ("launch:\n- node: {pkg: demo, exec: talker, remap: x}\n", ["list of mappings"], 2),
        (
            "launch:\n- node: {pkg: demo, exec: talker, remap: [{from: odom, to: '/\"t1\"/odom'}]}\n",
            ["invalid remap 'odom' -> '/\"t1\"/odom'", "to '/\"t1\"/odom' is not a ROS name"],
            2,
        ),
        (
            "launch:\n- let: {name: t, value: shadow cmd vel!}\n"
            "- node: {pkg: demo, exec: talker, remap: [{from: cmd_vel, to: $(var t)}]}\n",
            ["to 'shadow cmd vel!' is not a ROS name"],
            3,
        ),
        ("launch:\n- node: {pkg: demo, exec: talker, remap: [{from: cmd-vel, to: x}]}\n", ["from 'cmd-vel'"], 2),
        ("launch:\n- set_remap: {from: a, to: 2b}\n", ["to '2b' is not a ROS name"], 2),
        ("launch:\n- node: {pkg: demo, exec: talker, remap: [{from: __ns, to: x}]}\n", ["absolute namespace"], 2),
        (
            "launch:\n- node: {pkg: demo, exec: talker, name: a, namespace: /r}\n"
            "- group: [{push_ros_namespace: {namespace: r}}, {node: {pkg: demo, exec: listener, name: a}}]\n",
            ["two nodes are named /r/a (the first at 2:3)"],
            3,
        ),
        ("launch:\n- group: {scoped: 3, children: []}\n", ["'scoped' of 'group' must be true or false"], 2),
        ("launch:\n- group: {scoped: false}\n", ["needs a list of actions"], 2),
        ("launch:\n- node: {pkg: demo, exec: talker}\n  other: 1\n", ["exactly one key"], 2),
        ("launch:\n- push_ros_namespace: robot1\n", ["needs a mapping"], 2),
        ("nodes: []\n", ["single key 'launch'"], 1),
        ("launch: {node: {}}\n", ["must be a list"], 1),
        ("launch:\n- node: {pkg: demo\n", ["invalid YAML"], None),
    ],
)
def test_refusals(load, text, fragments, line):
    refused(load, text, *fragments, line=line)


def test_refusal_in_a_skipped_branch_still_refused(load):
    refused(
        load,
        """
        launch:
        - group:
            if: 'false'
            children:
            - shutdown: {reason: x}
    """,
        "action 'shutdown' needs the ros2 backend",
        line=5,
    )


def test_non_yaml_launch_file_refused(demo, tmp_path):
    path = tmp_path / "robot.launch.py"
    path.write_text("def generate_launch_description(): ...\n")
    with pytest.raises(LaunchFileError, match="Python launch file runs only under `ros2 launch`"):
        load_launch_file(path, env=demo.env())


def test_missing_file(demo, tmp_path):
    with pytest.raises(LaunchFileError, match="no such launch file"):
        check_launch_file(tmp_path / "nope.launch.yaml", env=demo.env())


def test_check_writes_nothing(demo, write_launch, tmp_path):
    path = write_launch(
        "launch:\n- node: {pkg: demo, exec: talker, name: t, namespace: n, param: [{name: a, value: 1}]}\n"
    )
    before = set(tmp_path.rglob("*"))
    assert check_launch_file(path, env=demo.env()) == {}
    assert set(tmp_path.rglob("*")) == before


def test_nodes_of_one_name_that_do_not_both_run_are_not_refused(load):
    plan = load("""
        launch:
        - node: {pkg: demo, exec: talker, name: a, if: 'false'}
        - node: {pkg: demo, exec: talker, name: a}
        - node: {pkg: demo, exec: talker, name: a, namespace: other}
    """)
    assert [node.fqn for node in plan.nodes] == ["/a", "/other/a"]
