"""The one-line rule for every command: bad input, from any file or argument, is one printable line
`fleet: error: FILE:LINE:COL: problem` of at most 300 characters, exit code 2, nothing done."""

from __future__ import annotations

import subprocess
import sys

import pytest

from fleet.errors import MAX_LINE, FleetError, Location, one_line
from tests.checkout import FLEETS, run_fleet
from tests.spec.test_bad_input import run_cli

BOMB = "launch:\n" + "".join(
    f"- &l{level} [{', '.join([f'*l{level - 1}'] * 10) if level else ', '.join(['x'] * 10)}]\n" for level in range(9)
)


def one_error_line(capsys, args: list[str]) -> str:
    code, _, stderr = run_cli(args, capsys)
    assert code == 2, stderr
    assert stderr.count("\n") == 1 and stderr.startswith("fleet: error: "), stderr
    line = stderr.rstrip("\n")
    assert len(line) <= MAX_LINE and line.isprintable(), line
    return line


def test_control_characters_are_escaped():
    assert one_line("a\nb\r\tc\x00\x1b[31m\u2028\u202e\x7f") == "a\\nb\\r\\tc\\x00\\x1b[31m\\u2028\\u202e\\x7f"


def test_long_values_keep_their_ends_and_the_place_stays_readable():
    error = FleetError(
        f"unknown key {'k' * 5000 + 'END'!r} in robots[0]", Location("/very/" + "deep/" * 10 + "f.yaml", 3, 4)
    )
    line = error.line()
    assert len(line) <= MAX_LINE
    assert "/f.yaml:3:4: unknown key 'kkkk" in line and "kkkEND' in robots[0]" in line
    many = FleetError("word " * 500, Location("f.yaml", 1, 1)).line()
    assert len(many) <= MAX_LINE and many.startswith("fleet: error: f.yaml:1:1: word word") and " ... " in many


def test_an_error_without_a_file_is_one_in_the_command_line():
    assert FleetError("bad option").line() == "fleet: error: <command line>: bad option"


@pytest.mark.parametrize(
    "args, expected",
    [
        (["render", "--bogus"], "<command line>: fleet render: No such option: --bogus"),
        (["render"], "<command line>: fleet render: Missing argument"),
        (["render", "x.yaml", "--format", "xml"], "Invalid value for '--format'"),
        (["deploy", "x.yaml", "--timeout", "soon"], "Invalid value for '--timeout'"),
        (["nosuchcommand"], "No such command 'nosuchcommand'"),
        (["dashboard", "--port", "99999"], "Invalid value for '--port'"),  # before connecting anywhere
        (["deploy", str(FLEETS / "two_robots.yaml"), "--timeout", "-1"], "Invalid value for '--timeout'"),
        (["logs", "robot1", "--tail", "-3"], "Invalid value for '--tail'"),
        (["logs", "robot1", "--tail", "20000"], "less than or equal to 10000"),  # what an agent answers
        # Values ROS cannot hold are refused before anything is asked of the robot's node.
        (["param", "set", "robot1", "controller", "max_speed", "{a: 1}"], "VALUE {a: 1}: dict is not a ROS parameter"),
        (["param", "set", "robot1", "controller", "max_speed", "[1, 2.5]"], "VALUE [1, 2.5]: mixed-type list"),
    ],
)
def test_usage_errors_are_one_line(capsys, args, expected):
    assert expected in one_error_line(capsys, args)


def test_help_is_still_help(capsys):
    code, stdout, _ = run_cli([], capsys)
    assert code == 2 and "Usage: fleet" in stdout and "render" in stdout


def test_output_directory_that_is_a_file(tmp_path, capsys):
    spec = tmp_path / "fleet.yaml"
    spec.write_text("fleet: demo\nrobots: [{name: r1}]\n")
    output = tmp_path / "out"
    output.write_text("mine")
    line = one_error_line(capsys, ["render", str(spec), "-o", str(output)])
    assert f"{output}: output directory is a file" in line
    line = one_error_line(capsys, ["render", str(spec), "-o", str(output / "sub")])
    assert f"cannot be made: {output} is a file" in line
    assert output.read_text() == "mine"


def test_an_empty_endpoint_is_refused_not_taken_for_the_default(capsys):
    line = one_error_line(capsys, ["status", "--connect", ""])
    assert line == "fleet: error: <command line>: endpoint '' is not PROTOCOL/HOST:PORT (such as tcp/10.0.0.1:7447)"


def test_a_zenoh_config_that_is_a_directory_is_said_so(tmp_path, capsys):
    line = one_error_line(capsys, ["status", "--zenoh-config", str(tmp_path)])
    assert line == f"fleet: error: {tmp_path}: a directory, not a Zenoh config file"


@pytest.mark.parametrize(
    "name, text, expected",
    [
        (
            "zenoh.json5",
            '{mode: "client",\n  connect: {endpoints: [1,}\n',
            ":2:27: invalid Zenoh config: expected array, ",
        ),
        ("zenoh.json5", "{mode: 5}", ":1:8: invalid Zenoh config: invalid type: integer `5`, expected either 'router'"),
        ("zenoh.yaml", "mode: client\nconnect:\n  endpoints: 5\n", ":3:14: invalid Zenoh config: connect.endpoints: "),
        (
            "zenoh.txt",
            "{}",
            ": invalid Zenoh config: Unsupported file type '.txt' (.json, .json5 and .yaml are supported)",
        ),
    ],
)
def test_a_zenoh_config_zenoh_cannot_read_is_placed_at_its_line(tmp_path, capsys, name, text, expected):
    """At the place in the file Zenoh names: not in a caret drawn over several lines (JSON5
    syntax), nor with the place in Zenoh's Rust source that noticed it."""
    config = tmp_path / name
    config.write_text(text)
    line = one_error_line(capsys, ["status", "--zenoh-config", str(config)])
    assert line.startswith(f"fleet: error: {config}{expected}") and ".rs:" not in line, line


def test_certs_into_a_place_no_directory_can_be_made(tmp_path, capsys):
    """Said as render says it, not as a traceback from the authority's mkdir."""
    (tmp_path / "file").write_text("")
    out = tmp_path / "file" / "certs"
    line = one_error_line(capsys, ["certs", str(FLEETS / "two_robots.yaml"), "--out", str(out)])
    assert line == f"fleet: error: {out}: cannot write {out}: Not a directory"


def test_a_state_directory_no_directory_can_be_is_refused_before_anything_starts(capsys, monkeypatch, tmp_path):
    """$FLEET_STATE_DIR or --state-dir naming a file (or a place under one): one line, not a
    traceback from the daemon's mkdir."""
    file = tmp_path / "state"
    file.write_text("")
    monkeypatch.setenv("FLEET_STATE_DIR", str(file))
    for args in (["up"], ["down", "--all"]):
        line = one_error_line(capsys, args)
        assert line == f"fleet: error: {file}: state directory ($FLEET_STATE_DIR) is a file, not a directory", line
    under = file / "agent"
    line = one_error_line(capsys, ["agent", "--name", "a1", "--connect", "tcp/127.0.0.1:1", "--state-dir", str(under)])
    assert line == f"fleet: error: {under}: state directory cannot be made: {file} is a file, not a directory", line
    assert file.read_text() == ""


def test_a_world_status_file_the_world_could_not_write_is_refused_before_it_starts(tmp_path):
    """It wrote a traceback a few times a second instead (a subprocess: a world that starts runs
    until it is stopped)."""
    assert run_fleet(["render", str(FLEETS / "two_robots.yaml"), "-o", str(tmp_path / "out")]) == 0
    config = tmp_path / "out" / "world" / "world.yaml"
    (tmp_path / "file").write_text("")
    for status_file, problem in [
        (tmp_path, "the status file is a directory: give a file's name"),
        (tmp_path / "file" / "w.json", "the status file's directory is a file, not a directory"),
    ]:
        args = ["world", "--config", str(config), "--status-file", str(status_file)]
        done = subprocess.run([sys.executable, "-m", "fleet", *args], capture_output=True, text=True, timeout=60)
        assert done.returncode == 2 and done.stderr == f"fleet: error: {status_file}: {problem}\n", done.stderr


def test_output_directory_fleet_did_not_write_is_refused(tmp_path, capsys):
    spec = tmp_path / "fleet.yaml"
    spec.write_text("fleet: demo\nrobots: [{name: r1}]\n")
    output = tmp_path / "out"
    output.mkdir()
    (output / "notes.txt").write_text("mine")
    line = one_error_line(capsys, ["render", str(spec), "-o", str(output)])
    assert f"{output}: output directory is not empty and holds no earlier render (no .fleet-render)" in line
    assert [path.name for path in output.iterdir()] == ["notes.txt"]


def test_run_names_the_problem_and_offers_ros2_launch_only_where_it_runs_the_file(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("PATH", "/usr/bin:/bin")  # no `ros2`: the embedded runner
    no_ros2 = " (and `ros2` is not on PATH to run it with ros2 launch)"
    missing = tmp_path / "robot1.py"
    line = one_error_line(capsys, ["run", str(missing)])
    assert line == f"fleet: error: {missing}: no such launch file"
    # Said once, as read_input says it of every input file (it was "cannot read launch file: " twice).
    line = one_error_line(capsys, ["run", str(tmp_path)])
    assert line == f"fleet: error: {tmp_path}: cannot read launch file: Is a directory"
    bad = tmp_path / "bad.launch.yaml"
    bad.write_text("launch: [\n")
    line = one_error_line(capsys, ["run", str(bad)])
    assert "invalid YAML" in line and no_ros2 not in line
    python = tmp_path / "robot1.launch.py"
    python.write_text("")
    line = one_error_line(capsys, ["run", str(python)])
    assert "a Python launch file runs only under `ros2 launch`" in line and line.endswith(no_ros2)
    ros2_only = tmp_path / "stop.launch.yaml"
    ros2_only.write_text("launch:\n- log: {message: $(anon x)}\n")
    assert one_error_line(capsys, ["run", str(ros2_only)]).endswith(no_ros2)


@pytest.mark.parametrize("mode", [["-s"], ["-p"], []])
def test_run_options_are_checked_before_the_file_is_read(tmp_path, capsys, mode):
    launch = tmp_path / "a.launch.yaml"
    launch.write_text("launch: []\n")
    for option, value, allowed in (
        ("--isolation", "vm", "'process', 'robot'"),
        ("--isolation", "agent", "'process', 'robot'"),
        ("--backend", "docker", "'auto', 'embedded', 'ros2'"),
    ):
        code, stdout, stderr = run_cli(["run", str(launch), option, value, *mode], capsys)
        assert code == 2 and stdout == ""
        problem = f"Invalid value for '{option}': '{value}' is not one of {allowed}."
        assert stderr == f"fleet: error: <command line>: fleet run: {problem}\n"


def test_launch_file_alias_bomb_is_refused_fast(tmp_path, capsys):
    launch = tmp_path / "bomb.launch.yaml"
    launch.write_text(BOMB)
    line = one_error_line(capsys, ["run", str(launch)])
    assert f"{launch}:" in line and "aliases expand this document to more than" in line


def test_launch_argument_without_a_value(tmp_path, capsys):
    launch = tmp_path / "x.launch.yaml"
    launch.write_text("launch: []\n")
    line = one_error_line(capsys, ["run", str(launch), "speed=1\x1b[2J"])
    assert "speed=1\\x1b[2J: launch arguments are name:=value" in line


def test_world_description_limits(tmp_path, capsys):
    world = tmp_path / "world.yaml"
    world.write_text("robots: &r [{name: a, pose: *r}]\n")
    line = one_error_line(capsys, ["world", "--config", str(world)])
    assert f"{world}:1:" in line and "refers to the collection it is in" in line


def test_parameter_value_of_param_set(capsys):
    line = one_error_line(capsys, ["param", "set", "r1", "controller", "max_speed", "[[[" * 30 + "]]]" * 30])
    assert "not a parameter value" in line and "too deep" in line


def test_status_file_nested_too_deeply(tmp_path, capsys):
    status = tmp_path / "world.status.json"
    status.write_text("[" * 100_000 + "]" * 100_000)
    line = one_error_line(capsys, ["snapshot", "--status-file", str(status), "-o", str(tmp_path / "w.png")])
    assert "no readable world status" in line


def test_a_named_pipe_nobody_writes_to_is_read_as_empty(tmp_path, capsys):
    """Reading waits for no writer: a FIFO given as the spec is refused at once, not a hang."""
    import os

    fifo = tmp_path / "spec.yaml"
    os.mkfifo(fifo)
    line = one_error_line(capsys, ["render", str(fifo)])
    assert f"{fifo}:1:1: a fleet spec is a mapping" in line


def test_output_into_a_closed_pipe_ends_quietly(tmp_path):
    """`fleet render SPEC | head -1`: the reader leaves early; fleet stops without a traceback."""
    import subprocess
    import sys

    spec = tmp_path / "many.yaml"  # a table far longer than a pipe holds, so writing it meets the closed pipe
    spec.write_text("fleet: many\nrobots:\n" + "".join(f"  - {{name: r{i}, pose: {{x: {i}}}}}\n" for i in range(250)))
    result = subprocess.run(
        f"{sys.executable} -m fleet render {spec} | head -c 10",
        shell=True,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert len(result.stdout) == 10
    assert "Traceback" not in result.stderr and "Error" not in result.stderr, result.stderr


@pytest.mark.parametrize(
    "args, expected",
    [
        (["status", "--connect", "not an address"], "endpoint 'not an address' is not PROTOCOL/HOST:PORT"),
        (["status", "--connect", "tcp/999.1.1.1:7447"], "'999.1.1.1' is not an IP address"),
        (["status", "--connect", "tcp/10.0.0.1"], "has no port from 0 to 65535"),
        (["deploy", str(FLEETS / "two_robots.yaml"), "--connect", "tcp/[::1]:70000"], "has no port from 0 to 65535"),
        (["router", "--listen", "tcp/bad_host!:7447"], "'bad_host!' is not a host name or an IP address"),
        (["status", "--connect", "tcp/::1:7447"], "an IPv6 address goes in brackets (tcp/[::1]:7447)"),
        # Only an IPv6 address is told to go in brackets: other text with a colon is no host.
        (["status", "--connect", "tcp/10.0.0.1:7447,tcp/10.0.0.2:7447"], "'10.0.0.1:7447,tcp/10.0.0.2' is not an IP"),
        (["status", "--connect", "tcp/[::1:7447"], "'[::1' is not an IP address"),
    ],
)
def test_an_endpoint_that_is_not_an_address(capsys, args, expected):
    """Refused before any connection is tried: one line, exit 2, and nothing deployed."""
    line = one_error_line(capsys, args)
    assert line.startswith("fleet: error: <command line>: ") and expected in line, line


@pytest.mark.parametrize(
    "endpoint, expected",
    [
        ("tcp/192.0.2.1:7447", "this computer cannot listen on 192.0.2.1 (Cannot assign requested address)"),
        ("tcp/127.0.0.1", "has no port from 0 to 65535"),
    ],
)
def test_up_refuses_an_endpoint_this_computer_cannot_listen_on(capsys, monkeypatch, tmp_path, endpoint, expected):
    """Refused before a running daemon would be stopped to move it there."""
    monkeypatch.setenv("FLEET_STATE_DIR", str(tmp_path))
    line = one_error_line(capsys, ["up", "--listen", endpoint])
    assert line.startswith(f"fleet: error: --listen: endpoint '{endpoint}'") and expected in line, line
    assert list(tmp_path.iterdir()) == []  # no daemon was started


def test_an_agent_given_another_agents_state_directory_is_bad_input(capsys, tmp_path):
    """It was a RuntimeError's traceback."""
    state = tmp_path / "state"
    state.mkdir()
    (state / "agent.json").write_text('{"name": "local"}')
    args = ["agent", "--name", "other", "--state-dir", str(state), "--connect", "tcp/127.0.0.1:1"]
    assert "the state directory of agent 'local', not 'other'" in one_error_line(capsys, args)
    (state / "agent.json").write_text("[")
    assert f"{state / 'agent.json'}: not an agent's marker file" in one_error_line(capsys, args)
