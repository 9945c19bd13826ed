"""Rendering: structure of generated launch files, parameter layering, hostile values."""

from __future__ import annotations

import ast
import errno
import json
import os
import textwrap
from pathlib import Path

import pytest
import yaml

from fleet.expand import expand_fleet
from fleet.expand.templating import builtin_template_dirs
from fleet.spec import parse_spec
from tests.checkout import FLEETS, run_fleet


def render_to(tmp_path: Path, spec: Path, *extra: str) -> Path:
    out = tmp_path / "out"
    assert run_fleet(["render", str(spec), "-o", str(out), *extra]) == 0
    return out


def files_under(directory: Path) -> list[str]:
    """The files in `directory` and below, by their paths relative to it."""
    return sorted(str(path.relative_to(directory)) for path in directory.rglob("*") if path.is_file())


def test_render_over_an_earlier_render_leaves_only_the_new_files(tmp_path):
    """Robots gone from the spec and formats no longer asked for leave no file behind; what
    others put in the directory stays, and the list cannot be made to remove files outside it."""
    out = render_to(tmp_path, FLEETS / "two_robots.yaml")
    (out / "robot1" / "notes.txt").write_text("mine")
    (out / "README").write_text("mine")
    victim = tmp_path / "victim.txt"
    victim.write_text("keep")
    with (out / ".fleet-render").open("a") as listing:
        listing.write(f"../victim.txt\n{victim}\nrobot1/../../victim.txt\n")
    spec = tmp_path / "three.yaml"
    spec.write_text((FLEETS / "two_robots.yaml").read_text().replace("name: robot2", "name: robot3"))
    render_to(tmp_path, spec, "--format", "yaml")
    files = files_under(out)
    assert files == [
        ".fleet-render",
        "README",
        "robot1/notes.txt",
        "robot1/robot1.launch.yaml",
        "robot1/robot1.params.yaml",
        "robot3/robot3.launch.yaml",
        "robot3/robot3.params.yaml",
        "world/world.launch.yaml",
        "world/world.yaml",
    ]
    assert not (out / "robot2").exists() and victim.read_text() == "keep"


def three_robots(tmp_path: Path) -> Path:
    spec = tmp_path / "three.yaml"
    robot3 = "  - name: robot3\n    pose: {x: 2.0, y: 3.0, yaw: 0.0}\n"
    spec.write_text((FLEETS / "two_robots.yaml").read_text() + robot3)
    return spec


def snapshot(directory: Path) -> dict[str, bytes | str]:
    """Every entry under `directory`: a file's bytes, or what a directory or symlink is."""
    return {
        str(path.relative_to(directory)): (
            f"-> {path.readlink()}" if path.is_symlink() else "dir" if path.is_dir() else path.read_bytes()
        )
        for path in directory.rglob("*")
    }


def render_error(capsys, spec: Path, out: Path) -> str:
    capsys.readouterr()
    assert run_fleet(["render", str(spec), "-o", str(out)]) == 2
    stderr = capsys.readouterr().err
    assert stderr.count("\n") == 1 and stderr.startswith("fleet: error: "), stderr
    return stderr.rstrip("\n")


def a_file_where_robot3s_directory_goes(out: Path) -> Path:
    (out / "robot3").write_text("notes")
    return out / "robot3"


def a_file_of_the_users_where_robot3s_parameters_go(out: Path) -> Path:
    (out / "robot3").mkdir()
    (out / "robot3" / "robot3.params.yaml").write_text("mine")
    return out / "robot3" / "robot3.params.yaml"


def a_symlink_out_of_the_directory_where_robot3s_directory_goes(out: Path) -> Path:
    (out / "robot3").symlink_to(out.parent)
    return out / "robot3"


def a_directory_where_a_listed_file_was(out: Path) -> Path:
    (out / "robot1" / "robot1.launch.py").unlink()
    (out / "robot1" / "robot1.launch.py").mkdir()
    return out / "robot1" / "robot1.launch.py"


@pytest.mark.parametrize(
    "in_the_way",
    [
        a_file_where_robot3s_directory_goes,
        a_file_of_the_users_where_robot3s_parameters_go,
        a_symlink_out_of_the_directory_where_robot3s_directory_goes,
        a_directory_where_a_listed_file_was,
    ],
)
def test_a_render_refused_for_what_is_in_its_way_leaves_the_directory_as_it_was(tmp_path, capsys, in_the_way):
    """Files fleet did not write are kept, so one where the new render would write refuses it,
    before the earlier render is removed: not a half-written directory behind an error."""
    out = render_to(tmp_path, FLEETS / "two_robots.yaml")
    place = in_the_way(out)
    before = snapshot(out)
    line = render_error(capsys, three_robots(tmp_path), out)
    assert f"{place}: " in line and "fleet did not write" in line
    assert snapshot(out) == before


@pytest.mark.parametrize(
    ("listing", "problem"),
    [
        (b"\xff\n", "not UTF-8 text"),
        (b"robot1/robot1.launch.yaml\n", "not a list fleet render wrote"),  # no header: someone else's file
    ],
)
def test_a_render_list_fleet_cannot_read_is_refused_not_followed(tmp_path, capsys, listing, problem):
    out = render_to(tmp_path, FLEETS / "two_robots.yaml")
    (out / ".fleet-render").write_bytes(listing)
    before = snapshot(out)
    line = render_error(capsys, FLEETS / "two_robots.yaml", out)
    assert line.startswith(f"fleet: error: {out / '.fleet-render'}: ") and problem in line
    assert snapshot(out) == before


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes whatever the permission bits say")
def test_a_render_into_a_place_it_cannot_write_is_refused_before_anything_is_removed(tmp_path, capsys):
    out = render_to(tmp_path, FLEETS / "two_robots.yaml")
    (out / "robot2").chmod(0o555)  # robot2's files cannot be removed
    try:
        before = snapshot(out)
        line = render_error(capsys, three_robots(tmp_path), out)
        assert f"{out / 'robot2'}: " in line and "cannot write" in line
        assert snapshot(out) == before
    finally:
        (out / "robot2").chmod(0o755)


def test_a_render_that_fails_half_way_lists_what_it_left_and_the_next_removes_it(tmp_path, capsys, monkeypatch):
    """A disk that fills half way: one error line, and the list names exactly fleet's files on
    disk (the half-written one too), so that the next render removes them all."""
    out = render_to(tmp_path, FLEETS / "two_robots.yaml")
    (out / "robot1" / "notes.txt").write_text("mine")
    spec = three_robots(tmp_path)
    write_text = Path.write_text
    calls = []

    def fill_the_disk(path, text, *args, **kwargs):
        calls.append(path)
        if len(calls) < 4:
            return write_text(path, text, *args, **kwargs)
        write_text(path, text[: len(text) // 2], *args, **kwargs)
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(Path, "write_text", fill_the_disk)
    line = render_error(capsys, spec, out)
    monkeypatch.undo()
    assert line.endswith(f"cannot write {calls[-1]}: No space left on device")
    header, *listed = (out / ".fleet-render").read_text().splitlines()
    on_disk = set(files_under(out))
    assert header.startswith("# written by fleet render") and len(listed) == 4
    assert set(listed) == on_disk - {".fleet-render", "robot1/notes.txt"}
    render_to(tmp_path, FLEETS / "two_robots.yaml", "--format", "yaml")
    files = files_under(out)
    assert files == [
        ".fleet-render",
        "robot1/notes.txt",
        "robot1/robot1.launch.yaml",
        "robot1/robot1.params.yaml",
        "robot2/robot2.launch.yaml",
        "robot2/robot2.params.yaml",
        "world/world.launch.yaml",
        "world/world.yaml",
    ]


def launch_nodes(actions: list, namespace: str = "/") -> list[tuple[str, dict]]:
    """(pushed namespace, node body) for every node in a parsed YAML launch document."""
    found = []
    for action in actions:
        ((kind, body),) = action.items()
        if kind == "push_ros_namespace":
            namespace = body["namespace"]
        elif kind == "group":
            found += launch_nodes(body, namespace)
        elif kind == "node":
            found.append((namespace, body))
    return found


def test_two_robots_yaml_launch_structure(tmp_path):
    out = render_to(tmp_path, FLEETS / "two_robots.yaml")
    for robot in ("robot1", "robot2"):
        document = yaml.safe_load((out / robot / f"{robot}.launch.yaml").read_text())
        group = next(a["group"] for a in document["launch"] if "group" in a)
        assert {"push_ros_namespace": {"namespace": f"/{robot}"}} in group
        nodes = launch_nodes(document["launch"])
        assert sorted(body["name"] for _, body in nodes) == ["battery", "controller", "safety"]
        for namespace, body in nodes:
            assert namespace == f"/{robot}"
            assert body["pkg"] == "fleet_nodes" and body["exec"] == body["name"]
            assert {"from": f"$(dirname)/{robot}.params.yaml"} in body["param"]
    world = yaml.safe_load((out / "world" / "world.launch.yaml").read_text())
    ((_, body),) = launch_nodes(world["launch"])
    assert body["exec"] == "world" and "$(dirname)/world.yaml" in body["args"]


def _calls(tree: ast.AST) -> list[ast.Call]:
    return [node for node in ast.walk(tree) if isinstance(node, ast.Call)]


def test_two_robots_python_launch_structure(tmp_path):
    out = render_to(tmp_path, FLEETS / "two_robots.yaml")
    for robot in ("robot1", "robot2"):
        tree = ast.parse((out / robot / f"{robot}.launch.py").read_text())
        functions = [n.name for n in tree.body if isinstance(n, ast.FunctionDef)]
        assert functions == ["generate_launch_description"]
        calls = _calls(tree)
        names = [c.func.id for c in calls if isinstance(c.func, ast.Name)]
        assert names.count("GroupAction") == 1 and names.count("Node") == 3
        push = next(c for c in calls if isinstance(c.func, ast.Name) and c.func.id == "PushRosNamespace")
        assert ast.literal_eval(push.args[0]) == f"/{robot}"
        group = next(c for c in calls if isinstance(c.func, ast.Name) and c.func.id == "GroupAction")
        children = group.args[0]
        assert isinstance(children, ast.List)
        assert any(
            isinstance(e, ast.Call) and isinstance(e.func, ast.Name) and e.func.id == "PushRosNamespace"
            for e in children.elts
        )
        for node in (c for c in calls if isinstance(c.func, ast.Name) and c.func.id == "Node"):
            keywords = {k.arg: k.value for k in node.keywords}
            assert ast.literal_eval(keywords["package"]) == "fleet_nodes"
            parameters = keywords["parameters"]
            assert isinstance(parameters, ast.List)
            params_file = parameters.elts[0]
            assert isinstance(params_file, ast.List)
            assert ast.literal_eval(params_file.elts[1]) == f"/{robot}.params.yaml"
            assert ast.unparse(params_file.elts[0]) == "ThisLaunchFileDir()"


def test_params_file_sections_and_override_order(tmp_path):
    out = render_to(tmp_path, FLEETS / "two_robots.yaml", "--set", "robot2.safety.safety_distance=0.6")
    robot1 = yaml.safe_load((out / "robot1" / "robot1.params.yaml").read_text())
    robot2 = yaml.safe_load((out / "robot2" / "robot2.params.yaml").read_text())
    assert set(robot1) == {"/robot1/controller", "/robot1/battery", "/robot1/safety"}
    assert robot1["/robot1/controller"]["ros__parameters"]["max_speed"] == 0.4  # fleet defaults beat template (0.5)
    assert robot2["/robot2/controller"]["ros__parameters"]["max_speed"] == 0.8  # robot beats fleet defaults
    assert robot2["/robot2/safety"]["ros__parameters"]["safety_distance"] == 0.6  # --set beats everything
    assert robot1["/robot1/safety"]["ros__parameters"]["safety_distance"] == 0.4
    assert robot1["/robot1/controller"]["ros__parameters"]["max_turn_rate"] == 1.5  # template default


def test_layers_precedence_and_explain(tmp_path):
    spec = parse_spec(
        textwrap.dedent("""\
        fleet: demo
        defaults:
          parameters: {controller: {max_speed: 0.3, goal_tolerance: 0.2}}
        robots:
          - name: a
            parameters: {controller: {max_speed: 0.6, waypoints: [1, 0, 2, 0]}}
          - name: b
        """),
        "demo.yaml",
    )
    expansion = expand_fleet(spec, ["a.controller.goal_tolerance=0.05", "b.controller.loop=false"])
    plan_a, plan_b = expansion.robot("a"), expansion.robot("b")
    assert plan_a is not None and plan_b is not None
    a, b = plan_a.parameters, plan_b.parameters
    assert a.effective()["controller"]["max_speed"] == 0.6
    assert a.effective()["controller"]["waypoints"] == [1.0, 0.0, 2.0, 0.0]  # ints promoted to the declared doubles
    assert [s.layer for s in a.explain("controller", "goal_tolerance")] == ["template", "defaults", "--set"]
    assert a.effective()["controller"]["goal_tolerance"] == 0.05
    assert b.effective()["controller"]["max_speed"] == 0.3
    assert b.effective()["controller"]["loop"] is False
    assert [s.layer for s in a.explain("controller", "max_speed")] == ["template", "defaults", "robot"]
    assert a.explain("controller", "max_speed")[-1].source == "demo.yaml:6:42"


def test_explain_cli(tmp_path, capsys):
    assert (
        run_fleet(
            [
                "render",
                str(FLEETS / "two_robots.yaml"),
                "--explain",
                "robot2.controller.max_speed",
                "--set",
                "robot2.controller.max_speed=1.2",
                "--json",
            ]
        )
        == 0
    )
    import json

    data = json.loads(capsys.readouterr().out)
    assert data["value"] == 1.2
    assert [layer["layer"] for layer in data["layers"]] == ["template", "defaults", "robot", "--set"]
    assert [layer["value"] for layer in data["layers"]] == [0.5, 0.4, 0.8, 1.2]


def test_explain_warns_of_a_parameter_the_template_does_not_list(capsys):
    """The layers of a mistyped name still end in "effective"; the warning says the node may
    never read it, as render and deploy do."""
    args = ["render", str(FLEETS / "two_robots.yaml"), "--explain", "robot1.controller.max_sped"]
    assert run_fleet([*args, "--set", "robot1.controller.max_sped=1.0", "--json"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["layers"][-1]["layer"] == "--set"
    assert "controller.max_sped is not a parameter of the template's controller defaults" in captured.err
    assert "did you mean 'max_speed'?" in captured.err


def test_explain_names_the_files_fleet_found_relative_to_the_working_directory(capsys, monkeypatch):
    """As a compiler names the files it found: the built-in template from the directory holding
    it (`templates/...` from the checkout), the spec as it was given."""
    templates = builtin_template_dirs()[0]
    monkeypatch.chdir(templates.parent)
    spec = FLEETS / "two_robots.yaml"
    assert run_fleet(["render", str(spec), "--explain", "robot2.controller.max_speed", "--json"]) == 0
    sources = [layer["source"] for layer in json.loads(capsys.readouterr().out)["layers"]]
    assert sources[0].startswith(f"{templates.name}/diff_drive.params.yaml:")
    assert sources[1].startswith(f"{spec}:")


def test_dry_plan_json_lists_robots_nodes_parameters(capsys):
    assert run_fleet(["render", str(FLEETS / "two_robots.yaml"), "--json"]) == 0
    import json

    data = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in data["robots"]] == ["robot1", "robot2"]
    assert data["robots"][1]["parameters"]["controller"]["max_speed"] == {"value": 0.8, "from": "robot"}
    assert [n["fqn"] for n in data["robots"][0]["nodes"]] == ["/robot1/controller", "/robot1/battery", "/robot1/safety"]
    assert data["agents"]["local"]["units"] == ["robot1", "robot2", "world"]


def test_format_option(tmp_path):
    out = render_to(tmp_path, FLEETS / "two_robots.yaml", "--format", "yaml")
    assert sorted(p.name for p in (out / "robot1").iterdir()) == ["robot1.launch.yaml", "robot1.params.yaml"]


def test_bigger_example_renders(tmp_path):
    out = render_to(tmp_path, FLEETS / "warehouse_ten.yaml")
    assert len([p for p in out.iterdir() if p.is_dir()]) == 11
    r08 = yaml.safe_load((out / "r08" / "r08.launch.yaml").read_text())
    arg = next(a["arg"] for a in r08["launch"] if "arg" in a and a["arg"]["name"] == "enable_safety")
    assert arg["default"] == "false"


HOSTILE = [
    'x"}\n- node: {pkg: evil, exec: evil, name: evil}\n#',
    "'); import os; os.system('touch /tmp/pwned'); ('",
    "$ (env HOME)\n  - node: {pkg: x}",
    "{{ 7 * 7 }}",
    "a: b\n/robot2/controller:\n  ros__parameters: {max_speed: 99.0}",
    "\u2028\u0085 line separators",
]


def logger_level(value: str) -> str:
    """A --log-level rcl takes whatever the logger's name: the value is carried in that name."""
    return f"{value}:=info"


def test_hostile_values_stay_inert(tmp_path):
    """Quotes, newlines, YAML, Python and Jinja syntax in values never add actions, nodes or code."""
    spec_path = tmp_path / "hostile.yaml"
    robots = []
    for index, value in enumerate(HOSTILE):
        robots.append(
            {
                "name": f"r{index}",
                "launch_args": {"log_level": logger_level(value)},
                "parameters": {"controller": {"waypoints": [1.0, 0.0]}, "battery": {"label": value}},
            }
        )
    spec_path.write_text(yaml.safe_dump({"fleet": "hostile", "robots": robots}))
    out = render_to(tmp_path, spec_path)
    for index, value in enumerate(HOSTILE):
        robot = f"r{index}"
        document = yaml.safe_load((out / robot / f"{robot}.launch.yaml").read_text())
        assert len(launch_nodes(document["launch"])) == 3
        assert all(body["pkg"] == "fleet_nodes" for _, body in launch_nodes(document["launch"]))
        arg = next(a["arg"] for a in document["launch"] if "arg" in a and a["arg"]["name"] == "log_level")
        assert arg["default"] == logger_level(value)  # the exact string, as one inert value
        source = (out / robot / f"{robot}.launch.py").read_text()
        tree = ast.parse(source)
        called = {c.func.id for c in _calls(tree) if isinstance(c.func, ast.Name)}
        assert called <= {
            "LaunchDescription",
            "DeclareLaunchArgument",
            "GroupAction",
            "PushRosNamespace",
            "SetEnvironmentVariable",
            "SetLaunchConfiguration",
            "Node",
            "IfCondition",
            "LaunchConfiguration",
            "ThisLaunchFileDir",
        }
        assert not [c for c in _calls(tree) if isinstance(c.func, ast.Attribute)]
        constants = {n.value for n in ast.walk(tree) if isinstance(n, ast.Constant)}
        assert logger_level(value) in constants
        params = yaml.safe_load((out / robot / f"{robot}.params.yaml").read_text())
        assert set(params) == {f"/{robot}/controller", f"/{robot}/battery", f"/{robot}/safety"}
        assert params[f"/{robot}/battery"]["ros__parameters"]["label"] == value


def test_launch_substitutions_in_values_are_rejected(tmp_path):
    """`$(command ...)` in a launch argument would run a shell under ros2 launch."""
    import pytest

    from fleet.errors import SpecError

    with pytest.raises(SpecError, match="launch substitution") as error:
        parse_spec("fleet: f\nrobots:\n- name: r1\n  launch_args: {log_level: $(command rm -rf ~)}\n", "f.yaml")
    assert str(error.value).startswith("f.yaml:4:")


def test_hostile_robot_names_are_rejected():
    import pytest

    from fleet.errors import SpecError

    for name in ['r1"; rm -rf /', "r1\n- node", "r1/../r2", "$(env HOME)", "{{x}}"]:
        with pytest.raises(SpecError, match="not a valid ROS name"):
            parse_spec(yaml.safe_dump({"fleet": "f", "robots": [{"name": name}]}), "f.yaml")


def test_params_emitter_round_trips_through_yaml():
    from fleet.expand import yaml_emit

    tree = {
        "/r1/controller": {
            "ros__parameters": {
                "f": 1e-05,
                "g": 2.0,
                "h": -3.5e20,
                "i": 7,
                "b": True,
                "s": 'a: b\n- c "q" \u2028',
                "e": "",
                "yes_string": "yes",
                "num_string": "1.5",
                "lf": [1.0, 2.5],
                "ls": ["x", "true", "On", "null", "/a/b", "0x1f", "1_000", "a b"],
                "lb": [False],
                "pid": {"kp": 1.5, "inner": {"x": 1}},
                "inf": float("inf"),
            }
        }
    }
    text = yaml_emit.emit(tree)
    assert yaml.safe_load(text) == tree
    world = {
        "obstacles": [{"name": "a", "position": [1.0, 2.0]}, {"name": "b", "size": [1.0, 1.0, 1.0]}],
        "robots": [{"name": "r1", "model": {"type": "light"}, "pose": {"x": 0.0}}],
        "empty": {},
    }
    assert yaml.safe_load(yaml_emit.emit(world)) == world


def test_shape_cache_matches_full_render(tmp_path):
    """Robots reusing a parsed template shape get exactly what a full parse would give."""
    from fleet.errors import Location
    from fleet.expand.rendered_launch import _NAME, LaunchRenderer
    from fleet.expand.templating import TemplateSet, builtin_template_dirs

    renderer = LaunchRenderer(TemplateSet(builtin_template_dirs()), "f")
    results = {}
    for name in ("a", "b"):
        context = {
            "robot": {"name": name, "namespace": f"/site/{name}", "agent": "local", "model": {}, "pose": {}},
            "fleet": {"name": "f", "domain_id": 0, "use_sim_time": True},
            "params_file": f"$(dirname)/{name}.params.yaml",
        }
        cached = renderer.render("diff_drive", context, {}, Location("x"))
        full = renderer._parse("diff_drive", context, {}, Location("x"), name)
        assert cached == full
        assert _NAME not in cached.python and _NAME not in cached.text
        results[name] = cached
    assert [n.fqn for n in results["b"].outline.nodes] == ["/site/b/controller", "/site/b/battery", "/site/b/safety"]


def test_deploy_dry_run_sends_nothing(tmp_path, capsys, monkeypatch):
    """--dry-run prints the plan and never connects (no router is running for this test)."""
    import json

    monkeypatch.setenv("FLEET_CONNECT", "tcp/127.0.0.1:9")  # would fail at once if it tried
    monkeypatch.setenv("FLEET_STATE_DIR", str(tmp_path / "state"))
    assert (
        run_fleet(
            [
                "deploy",
                str(FLEETS / "two_robots.yaml"),
                "--dry-run",
                "--json",
                "--set",
                "robot1.controller.max_speed=0.7",
            ]
        )
        == 0
    )
    data = json.loads(capsys.readouterr().out)
    assert data["robots"][0]["parameters"]["controller"]["max_speed"] == {"value": 0.7, "from": "--set"}
    assert not (tmp_path / "state").exists()
    # As a table it says that it sent nothing, and where to see what a deploy would change.
    assert run_fleet(["deploy", str(FLEETS / "two_robots.yaml"), "--dry-run"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "Effective parameters" in out and out.endswith(
        "dry run: nothing sent (`fleet diff SPEC` shows what a deploy would change)"
    ), out
    assert not (tmp_path / "state").exists()
    # The spec's warnings go to stderr, as a real deploy's do; the plan on stdout stays the plan.
    unknown = "robot1.controller.nosuch=1"
    assert run_fleet(["deploy", str(FLEETS / "two_robots.yaml"), "--dry-run", "--set", unknown]) == 0
    captured = capsys.readouterr()
    assert "warning:" not in captured.out
    assert f"warning: --set {unknown}: controller.nosuch is not a parameter" in captured.err


def test_a_node_started_without_the_parameter_file_is_warned_about_and_explained_as_not_given(tmp_path, capsys):
    """launch gives a node only the parameter files its `param` list names: a node the template
    starts without `from: {{ params_file }}` gets none of the values fleet writes for it, so render
    says so once per node, and --explain shows no layer as effective (it said the robot's was)."""
    from fleet.cli.plan_view import explain_data
    from fleet.runtime.launch_file import load_launch_file
    from tests.runtime.runtime_helpers import FakePrefix

    templates = tmp_path / "templates"
    templates.mkdir()
    (templates / "scout.launch.yaml.j2").write_text(
        textwrap.dedent("""\
        launch:
        - group:
          - push_ros_namespace: {namespace: {{ robot.namespace }}}
          - node: {pkg: fleet_nodes, exec: controller, name: controller}
          - node: {pkg: fleet_nodes, exec: battery, name: battery, param: [{from: {{ params_file }}}]}
          - node: {pkg: fleet_nodes, exec: safety, name: safety, param: [{name: stop_distance, value: 0.4}]}
        """)
    )
    (templates / "scout.params.yaml").write_text("controller: {max_speed: 0.3}\nbattery: {capacity: 80.0}\n")
    spec = tmp_path / "fleet.yaml"
    spec.write_text(
        "fleet: t\nros: {use_sim_time: false}\ntemplates: templates\ndefaults: {template: scout}\nrobots:\n"
        "- {name: a, parameters: {controller: {max_speed: 0.6}}}\n- {name: b}\n"
    )
    expansion = expand_fleet(parse_spec(spec.read_text(), str(spec)))
    assert expansion.warnings == [
        "a/a.launch.yaml:4:5: node controller is started without the robot's parameter file, so none of its "
        "parameters there reach it (max_speed); add `- from: {{ params_file }}` to its param list in template "
        "scout (and 1 more place)"
    ]
    explained = explain_data(expansion, "a.controller.max_speed")
    assert explained["value"] is None
    assert [(layer["layer"], layer["value"], layer["effective"]) for layer in explained["layers"]] == [
        ("template", 0.3, False),
        ("robot", 0.6, False),
        ("launch file", None, True),
    ]
    assert explained["layers"][-1]["source"] == "a/a.launch.yaml:4:5"
    # What the launch file gives such a node inline is what it gets (it said "in no layer").
    inline = explain_data(expansion, "a.safety.stop_distance")
    assert inline["value"] == 0.4
    assert [(layer["layer"], layer["source"], layer["effective"]) for layer in inline["layers"]] == [
        ("launch file", "a/a.launch.yaml:6:66", True)
    ]
    # A node given the file is explained as before, and a name no layer has is still refused.
    assert explain_data(expansion, "a.battery.capacity")["value"] == 80.0
    assert run_fleet(["render", str(spec), "--explain", "a.controller.nosuch"]) == 2
    assert run_fleet(["render", str(spec), "--explain", "a.controller.max_speed"]) == 0
    assert "a.controller.max_speed = (the node's own default)" in capsys.readouterr().out

    # What the warning says is what the runner does: the controller's command line has no file.
    out = render_to(tmp_path, spec)
    prefix = FakePrefix(tmp_path / "prefix")
    for exe in ("controller", "battery", "safety"):
        prefix.add(exe, "#!/bin/sh\nexec sleep 100\n", package="fleet_nodes")
    plan = load_launch_file(out / "a" / "a.launch.yaml", env=prefix.env(), params_dir=tmp_path / "params")
    commands = {node.name: node.cmd for node in plan.nodes}
    assert "--params-file" not in commands["controller"]
    assert str(out / "a" / "a.params.yaml") in commands["battery"]


@pytest.mark.parametrize("misnamed", ["scout.params.yml", "scout.param.yaml", "scout_params.yaml", "scout.yaml"])
def test_a_template_whose_defaults_look_misnamed_is_warned_about(tmp_path, misnamed):
    """Only `<template>.params.yaml` holds a template's defaults: under another name they are not
    read, so its nodes get none and no parameter name is checked.  Render says so, naming the
    file; another template's defaults and a template without any say nothing."""
    templates = tmp_path / "templates"
    templates.mkdir()
    for name in ("scout", "scout_2"):
        (templates / f"{name}.launch.yaml.j2").write_text(
            "launch:\n- node: {pkg: fleet_nodes, exec: controller, name: controller, "
            "param: [{from: {{ params_file }}}]}\n"
        )
    (templates / "scout_2.params.yaml").write_text("controller: {max_speed: 0.3}\n")
    spec = tmp_path / "fleet.yaml"
    spec.write_text(
        "fleet: t\nros: {use_sim_time: false}\ntemplates: templates\ndefaults: {template: scout}\n"
        "robots:\n- {name: a, parameters: {controller: {max_sped: 0.6}}}\n- {name: b, template: scout_2}\n"
    )
    assert expand_fleet(parse_spec(spec.read_text(), str(spec))).warnings == []
    (templates / misnamed).write_text("controller: {max_speed: 0.3}\n")
    assert expand_fleet(parse_spec(spec.read_text(), str(spec))).warnings == [
        f"{templates / misnamed}: not read as template scout's parameter defaults, which must be named "
        "scout.params.yaml; it has none"
    ]


def test_robots_on_sim_time_without_a_world_are_warned_about(tmp_path):
    """use_sim_time is on by default; a fleet without a world has nothing publishing /clock, so its
    nodes' time would stand still (timers never fire, as a first fleet of real robots found).
    Render says so at the spec's `ros`; a world, `use_sim_time: false` or robots that turn it
    off each say nothing."""
    spec = tmp_path / "fleet.yaml"

    def warnings(text: str) -> list[str]:
        spec.write_text(text)
        return expand_fleet(parse_spec(text, str(spec))).warnings

    robots = "robots:\n- {name: a}\n- {name: b}\n"
    assert warnings("fleet: t\nros: {domain_id: 5}\n" + robots) == [
        f"{spec}:2:1: robots a, b run on sim time (use_sim_time true, the default) but the fleet has no world "
        "to publish /clock: their nodes' time stands still until something else does; set "
        "`ros: {use_sim_time: false}` for real robots, or add a `world`"
    ]
    explicit = warnings(
        "fleet: t\nros:\n  use_sim_time: true\n" + robots + "- {name: c, launch_args: {use_sim_time: false}}\n"
    )
    assert explicit == [
        f"{spec}:3:3: robots a, b run on sim time (use_sim_time true) but the fleet has no world to publish "
        "/clock: their nodes' time stands still until something else does; set `ros: {use_sim_time: false}` "
        "for real robots, or add a `world`"
    ]
    assert warnings("fleet: t\nros: {use_sim_time: false}\n" + robots) == []
    assert warnings("fleet: t\ndefaults: {launch_args: {use_sim_time: false}}\n" + robots) == []
    assert warnings("fleet: t\nworld: {}\nrobots:\n- {name: a}\n- {name: b, pose: {x: 2.0}}\n") == []
    # A real robot of a fleet with a world would run on the simulation's clock.
    mixed = "fleet: t\nworld: {}\nrobots:\n- {name: a}\n- {name: b, simulated: false}\n"
    assert warnings(mixed) == [
        f"{spec}:1:1: robots b are real (simulated: false) but run on the world's sim time "
        "(use_sim_time true, the default): give each `launch_args: {use_sim_time: false}`"
    ]
    assert warnings(mixed.replace("simulated: false", "simulated: false, launch_args: {use_sim_time: false}")) == []


def test_the_sim_time_warning_follows_what_the_nodes_start_with(tmp_path):
    """A real robot's template of the user's own that gives its nodes wall time (a launch
    argument defaulting to false, or no use_sim_time at all) was warned about in every render
    and deploy of a fleet on sim time, and could not be silenced: the warning read the fleet's
    `ros.use_sim_time`, and `launch_args: {use_sim_time: ...}` is refused for a template without
    that argument.  It now reads what each node starts with."""
    templates = tmp_path / "templates"
    templates.mkdir()
    node = "  - node: {pkg: my_base, exec: base_driver, name: base_driver, param: [{from: {{ params_file }}}%s]}\n"
    head = "launch:\n%s- group:\n  - push_ros_namespace: {namespace: {{ robot.namespace }}}\n"
    wall_arg = '- arg: {name: use_sim_time, default: {{ arg("use_sim_time", false) }}}\n'
    inline = ", {name: use_sim_time, value: $(var use_sim_time)}"
    (templates / "wall.launch.yaml.j2").write_text(head % wall_arg + node % inline)
    (templates / "plain.launch.yaml.j2").write_text(head % "" + node % "")
    (templates / "sim.launch.yaml.j2").write_text(head % "" + node % ", {name: use_sim_time, value: true}")
    spec = tmp_path / "fleet.yaml"

    def warned(world: str, robot: str) -> list[str]:
        spec.write_text(f"fleet: t\ntemplates: templates\n{world}robots:\n- {{name: a}}\n- {{name: b, {robot}}}\n")
        return [warning.split(": ", 1)[1] for warning in expand_fleet(parse_spec(spec.read_text(), str(spec))).warnings]

    for template in ("wall", "plain"):
        assert warned("world: {}\n", f"template: {template}, simulated: false") == []
    assert warned("world: {}\n", "template: wall, simulated: false, launch_args: {use_sim_time: true}") == [
        "robots b are real (simulated: false) but run on the world's sim time (use_sim_time true, the default): "
        "give each `launch_args: {use_sim_time: false}`"
    ]
    assert warned("world: {}\n", "template: sim, simulated: false")[0].startswith("robots b are real")
    # Without a world, only the diff_drive robot `a` follows /clock.
    assert warned("", "template: wall")[0].startswith("robots a run on sim time")


def test_render_shows_no_model_or_pose_for_a_robot_the_world_does_not_host(tmp_path, capsys):
    """A real robot's row showed the light model and a pose at the origin, as if the world
    would spawn it there; without a world no robot has either."""
    spec = tmp_path / "mixed.yaml"
    spec.write_text(
        "fleet: mixed\nworld: {}\nrobots:\n- {name: sim1, pose: {x: 1.5}}\n"
        "- {name: bench, simulated: false, launch_args: {use_sim_time: false}}\n"
    )

    def model_and_pose() -> dict[str, list[str]]:
        """Robot -> what its row of the Robots table has after its nodes."""
        assert run_fleet(["render", str(spec)]) == 0
        rows = [line.split() for line in capsys.readouterr().out.splitlines()]
        return {row[0]: row[row.index("safety?") + 1 :] for row in rows if len(row) > 2 and row[2].startswith("/")}

    assert model_and_pose() == {"sim1": ["light", "1.50,0.00,0.00"], "bench": ["real"]}
    assert run_fleet(["render", str(spec), "--json"]) == 0
    robots = json.loads(capsys.readouterr().out)["robots"]
    assert [(robot["name"], robot["simulated"]) for robot in robots] == [("sim1", True), ("bench", False)]
    spec.write_text("fleet: reals\nros: {use_sim_time: false}\nrobots:\n- {name: r1}\n")
    assert model_and_pose() == {"r1": []}
