"""`fleet run`: foreground runner, screen output, exit codes, clean stop on SIGINT/SIGTERM."""

from __future__ import annotations

import re
import signal
import subprocess
import sys

import pytest

from fleet.testing.poll import poll
from tests.runtime.runtime_helpers import pid_alive

# The session's own line about a process, on screen and in its log: [INFO] [time] [hello-1]: ...
LAUNCH_LINE = re.compile(r"^\[(INFO|ERROR)\] \[[0-9.]+\] \[([a-z]+-[0-9]+)\]: (process [a-z ]+)")


def screen_launch_lines(out: str) -> list[tuple[str, str, str]]:
    """(severity, process, what) of the session's lines, in order of process (their order
    across processes is the processes' own)."""
    found = [(m[1], m[2], m[3]) for line in out.splitlines() if (m := LAUNCH_LINE.match(line))]
    return sorted(found, key=lambda found: found[1])


def fleet_run(prefix, *args, **kwargs) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "fleet", "run", *map(str, args)],
        env=prefix.env(PATH="/usr/bin:/bin"),  # no ros2 here: the embedded backend
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        **kwargs,
    )


def test_bad_file_is_one_line_and_exit_2(prefix, write_launch, tmp_path):
    path = write_launch("launch:\n- node: {pkg: demo, exec: x}\n- teleport: {}\n")
    runner = fleet_run(prefix, path, "--log-dir", tmp_path / "logs")
    out, err = runner.communicate(timeout=60)
    assert runner.returncode == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"fleet: error: {path}:3:3: unknown action 'teleport'")
    assert out == ""


def test_bad_launch_argument_syntax(prefix, write_launch, tmp_path):
    path = write_launch("launch: []\n")
    runner = fleet_run(prefix, path, "robot=r1", "--log-dir", tmp_path / "logs")
    _, err = runner.communicate(timeout=60)
    assert runner.returncode == 2
    assert "name:=value" in err


def test_screen_output_and_exit_codes(prefix, write_launch, tmp_path):
    prefix.add("hello", '#!/bin/sh\necho "hello $1"\n')
    prefix.add("fail", "#!/bin/sh\necho oops\nexit 5\n")
    path = write_launch("""
        launch:
        - arg: {name: who, default: nobody}
        - node: {pkg: demo, exec: hello, args: $(var who), output: screen}
        - node: {pkg: demo, exec: hello, args: quiet}
    """)
    runner = fleet_run(prefix, path, "who:=world", "--log-dir", tmp_path / "logs")
    out, err = runner.communicate(timeout=60)
    assert runner.returncode == 0, err
    # The screen has what output: screen nodes print, and (as ros2 launch prints them) when every
    # process started and how it ended; output: log nodes print only into their log.
    assert [line for line in out.splitlines() if not LAUNCH_LINE.match(line)] == ["[hello-1] hello world"], out
    assert screen_launch_lines(out) == [
        ("INFO", "hello-1", "process started with pid "),
        ("INFO", "hello-1", "process has finished cleanly "),
        ("INFO", "hello-2", "process started with pid "),
        ("INFO", "hello-2", "process has finished cleanly "),
    ]
    assert "hello-1" in err and "hello-2" in err  # the start-up status
    log = (tmp_path / "logs" / "hello-2.log").read_text().splitlines()
    assert [line for line in log if not LAUNCH_LINE.match(line)] == ["hello quiet"], log
    assert "process started" in log[0] and "finished cleanly" in log[-1], log

    failing = write_launch("launch:\n- node: {pkg: demo, exec: fail, output: screen}\n", "fail.launch.yaml")
    runner = fleet_run(prefix, failing, "--log-dir", tmp_path / "logs2")
    out, err = runner.communicate(timeout=60)
    assert runner.returncode == 1
    assert [line for line in out.splitlines() if not LAUNCH_LINE.match(line)] == ["[fail-1] oops"], out
    died = out.splitlines()[-1]
    assert LAUNCH_LINE.match(died) and "[fail-1]: process has died [pid " in died, out
    assert f"exit code 5, cmd: {prefix.root}" in died, died
    assert "fail-1" in err and "exit code 5" in err

    # An executable is no node: its rows name its process alone
    command = write_launch("launch:\n- executable: {cmd: sh -c 'exit 6'}\n", "command.launch.yaml")
    runner = fleet_run(prefix, command, "--log-dir", tmp_path / "logs3")
    _, err = runner.communicate(timeout=60)
    assert runner.returncode == 1
    assert "fleet: sh-1 failed with exit code 6" in err and "None" not in err, err


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_signal_stops_everything(prefix, write_launch, tmp_path, signum):
    prefix.add("sleeper", '#!/bin/sh\necho "pid $$"\nexec sleep 100\n')
    path = write_launch("""
        launch:
        - node: {pkg: demo, exec: sleeper, output: screen, respawn: 'true'}
        - node: {pkg: demo, exec: sleeper, output: screen}
    """)
    runner = fleet_run(prefix, path, "--log-dir", tmp_path / "logs")
    assert runner.stdout is not None and runner.stderr is not None
    pids: list[int] = []
    try:
        while len(pids) < 2:
            line = runner.stdout.readline()
            assert line, "fleet run ended early"
            if line.startswith("[sleeper-"):  # the node's own line, not launch's about it
                pids.append(int(line.split()[-1]))
        runner.send_signal(signum)
        runner.wait(timeout=20)
        assert runner.returncode == 0, runner.stderr.read()
        poll(
            lambda: [pid for pid in pids if pid_alive(pid)],
            until=lambda alive: not alive,
            timeout=5,
            interval=0.05,
            what="the nodes to end",
        )
    finally:
        runner.kill()
        runner.communicate()


def test_a_screen_that_goes_away_leaves_the_nodes_and_their_logs_running(prefix, write_launch, tmp_path):
    """`fleet run ... | head -1`: once the reader has gone, what the nodes print still goes to
    their logs, and nothing breaks (no traceback, the session stops cleanly)."""
    prefix.add("counter", '#!/bin/sh\ni=0\nwhile true; do i=$((i+1)); echo "count $i"; sleep 0.1; done\n')
    path = write_launch("launch:\n- node: {pkg: demo, exec: counter, output: screen}\n")
    runner = fleet_run(prefix, path, "--log-dir", tmp_path / "logs")
    assert runner.stdout is not None and runner.stderr is not None
    try:
        assert "process started" in runner.stdout.readline()
        runner.stdout.close()  # as `head -1` does
        log = tmp_path / "logs" / "counter-1.log"
        poll(lambda: "count 30" in log.read_text(), timeout=20, interval=0.1, what="the node's log to go on")
        runner.send_signal(signal.SIGINT)
        assert runner.wait(timeout=20) == 0
        assert "Traceback" not in runner.stderr.read()
    finally:
        runner.kill()
        runner.wait()


def test_show_args_and_print_like_ros2_launch(prefix, write_launch, tmp_path):
    path = write_launch("""
        launch:
        - arg: {name: robot, default: r1, description: The robot}
        - arg: {name: mode, default: slow, choice: [{value: slow}, {value: fast}]}
        - arg: {name: needed}
        - group:
          - push_ros_namespace: {namespace: $(var robot)}
          - node: {pkg: demo, exec: nowhere, name: n}
    """)
    runner = fleet_run(prefix, path, "--show-args")
    out, err = runner.communicate(timeout=60)
    assert runner.returncode == 0, err
    assert out == (
        "Arguments (pass arguments as '<name>:=<value>'):\n\n"
        "    'robot':\n        The robot\n        (default: 'r1')\n\n"
        "    'mode':\n        One of: ['slow', 'fast']\n        (default: 'slow')\n\n"
        "    'needed':\n        no description given\n"
    )
    runner = fleet_run(prefix, path, "-p")  # starts nothing: the missing executable is not looked up
    out, err = runner.communicate(timeout=60)
    assert runner.returncode == 0, err
    assert "└── GroupAction(scoped=True)" in out and "Node(package='demo', executable='nowhere', name='n')" in out


def test_log_actions_are_printed(prefix, write_launch, tmp_path):
    prefix.add("hello", "#!/bin/sh\nexit 0\n")
    path = write_launch("launch:\n- log: {message: hello $(var who)}\n- node: {pkg: demo, exec: hello}\n")
    runner = fleet_run(prefix, path, "who:=you", "--log-dir", tmp_path / "logs")
    out, err = runner.communicate(timeout=60)
    assert runner.returncode == 0, err
    # as ros2 launch does: the log action before the process it precedes starts
    assert out.splitlines()[0] == "[INFO] [launch.user]: hello you", out
    assert screen_launch_lines(out) == [
        ("INFO", "hello-1", "process started with pid "),
        ("INFO", "hello-1", "process has finished cleanly "),
    ]


def test_empty_launch_argument_is_malformed_as_in_ros2_launch(prefix, write_launch, tmp_path):
    path = write_launch("launch: []\n")
    runner = fleet_run(prefix, path, "robot:=", "--log-dir", tmp_path / "logs")
    _, err = runner.communicate(timeout=60)
    assert runner.returncode == 2
    assert err == "fleet: error: robot:=: launch arguments are name:=value\n"
    runner = fleet_run(prefix, path, "url:=a:=b", "--log-dir", tmp_path / "logs")  # ros2 launch takes this one
    assert runner.wait(timeout=60) == 0
