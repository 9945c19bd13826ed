"""The fleet_nodes ament index entries and executable lookup."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from fleet.errors import LaunchFileError
from fleet.runtime import ament


def test_ensure_writes_index_package_and_scripts(tmp_path):
    (tmp_path / "bin").mkdir()
    (tmp_path / "bin" / "python3").symlink_to(sys.executable)
    assert ament.ensure_ament_prefix(tmp_path) == tmp_path
    assert (tmp_path / "share/ament_index/resource_index/packages/fleet_nodes").read_text() == ""
    package_xml = (tmp_path / "share/fleet_nodes/package.xml").read_text()
    assert '<package format="3">' in package_xml and "<name>fleet_nodes</name>" in package_xml
    assert "<exec_depend>rclpy</exec_depend>" in package_xml
    for exe in ament.EXECUTABLES:
        script = tmp_path / "lib/fleet_nodes" / exe
        assert os.access(script, os.X_OK)
        text = script.read_text()
        assert text.startswith(f"#!{tmp_path}/bin/python3\n")
        assert f"from fleet.nodes.{exe} import main" in text


def test_ensure_is_idempotent_and_rewrites_only_changed_files(tmp_path):
    ament.ensure_ament_prefix(tmp_path)
    script = tmp_path / "lib/fleet_nodes/controller"
    before = {path: path.stat().st_mtime_ns for path in tmp_path.rglob("*") if path.is_file()}
    ament.ensure_ament_prefix(tmp_path)
    after = {path: path.stat().st_mtime_ns for path in tmp_path.rglob("*") if path.is_file()}
    assert before == after
    script.write_text("tampered")
    ament.ensure_ament_prefix(tmp_path)
    assert "fleet.nodes.controller" in script.read_text()
    assert not [path for path in script.parent.iterdir() if path.name.startswith(".")]


def test_script_without_bin_python_uses_this_interpreter(tmp_path):
    ament.ensure_ament_prefix(tmp_path)
    assert (tmp_path / "lib/fleet_nodes/battery").read_text().startswith(f"#!{sys.executable}\n")


def test_find_executable_first_prefix_wins(prefix, tmp_path):
    first = prefix.add("talker", "#!/bin/sh\n")
    second_root = tmp_path / "second"
    (second_root / ament.INDEX_DIR).mkdir(parents=True)
    (second_root / ament.INDEX_DIR / "demo").touch()
    search = os.pathsep.join([str(tmp_path / "empty"), str(prefix.root), str(second_root)])
    assert ament.find_executable("demo", "talker", search) == first
    # The package is found in the first prefix indexing it: no fallback to later prefixes.
    search = os.pathsep.join([str(second_root), str(prefix.root)])
    with pytest.raises(LaunchFileError, match="executable 'talker' of package 'demo' not found"):
        ament.find_executable("demo", "talker", search)


def test_a_mistyped_package_or_executable_is_told_what_there_is(prefix, tmp_path):
    """A typo is the usual cause.  The executable's error used to name only the file it looked
    for, between two long path lists, and a deploy's one error line (300 characters) cut out
    the middle of it: it now says what the package holds and the closest name."""
    prefix.add("wanderer", "#!/bin/sh\n")
    prefix.add("announcer", "#!/bin/sh\n")
    long_prefix = tmp_path / ("x" * 150)
    search = f"{long_prefix}:{prefix.root}"
    with pytest.raises(LaunchFileError) as caught:
        ament.find_executable("demo", "wandrer", search)
    problem = str(caught.value)
    assert "executable 'wandrer' of package 'demo' not found (did you mean 'wanderer'?)" in problem
    assert problem.endswith(f"{prefix.root / 'lib' / 'demo'} holds announcer, wanderer"), problem
    assert str(long_prefix) not in problem
    typo = r"package 'dmeo' not found in the ament index \(did you mean 'demo'\?\)"
    with pytest.raises(LaunchFileError, match=typo) as caught:
        ament.find_executable("dmeo", "wanderer", search)
    assert ament.missing_package(str(caught.value)) == "dmeo"  # deploy's hint still finds the name


def test_find_executable_errors_name_everything(prefix):
    prefix.add("talker", "#!/bin/sh\n")
    with pytest.raises(LaunchFileError) as caught:
        ament.find_executable("nopkg", "x", f"{prefix.root}:/elsewhere")
    assert "package 'nopkg'" in str(caught.value)
    assert str(prefix.root) in str(caught.value) and "/elsewhere" in str(caught.value)
    (prefix.root / "lib/demo/plain").write_text("not executable")
    with pytest.raises(LaunchFileError, match="'plain' of package 'demo'"):
        ament.find_executable("demo", "plain", str(prefix.root))


def test_ament_prefix_path_appends_ours_once():
    ours = sys.prefix
    assert ament.ament_prefix_path({}) == ours
    assert ament.ament_prefix_path({"AMENT_PREFIX_PATH": "/a:/b"}) == f"/a:/b:{ours}"
    assert ament.ament_prefix_path({"AMENT_PREFIX_PATH": f"{ours}:/a"}) == f"{ours}:/a"


def test_ament_prefix_command_prints_prefix():
    result = subprocess.run([sys.executable, "-m", "fleet", "ament-prefix"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == sys.prefix
    assert (ament.default_prefix() / "lib/fleet_nodes/composite").exists()


def test_a_missing_package_is_named_from_the_problem_an_agent_reports(tmp_path):
    """The deploy's hint reads the package from the agent's problem (which carries the launch
    file's place first) and looks for it in the shell's own search path."""
    (tmp_path / ament.INDEX_DIR).mkdir(parents=True)
    (tmp_path / ament.INDEX_DIR / "my_pkg").write_text("")
    with pytest.raises(LaunchFileError) as raised:
        ament.find_package_prefix("my_pkg", "/nowhere")
    problem = f"r1/r1.launch.yaml:12:5: {raised.value}"
    assert ament.missing_package(problem) == "my_pkg"
    assert ament.missing_package("r1/r1.launch.yaml:3:1: executable 'x' not found") is None
    assert ament.indexes("my_pkg", f"/nowhere{os.pathsep}{tmp_path}") == tmp_path
    assert ament.indexes("my_pkg", "/nowhere") is None
