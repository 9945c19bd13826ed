"""The supervisor with small real processes: logs, respawn, stop escalation, no leftovers."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from fleet.errors import FleetError, LaunchFileError
from fleet.rules import MAX_BACKOFF, MIN_BACKOFF, backoff_delay
from fleet.runtime import supervisor
from fleet.runtime.node_log import RCL_LOG_FILES_KEPT, rcl_log_dir
from fleet.runtime.processes import group_members
from fleet.runtime.supervisor import LaunchSession
from fleet.testing.poll import poll
from tests.runtime.runtime_helpers import pid_alive

CHATTY = """\
#!/bin/sh
echo "started with $*"
for i in 1 2 3 4 5; do echo "line $i"; done
echo "to stderr" >&2
exec sleep 100
"""
SLEEPER = "#!/bin/sh\nexec sleep 100\n"
# Ignores SIGINT (and its `exec`ed sleep inherits that), dies on SIGTERM.
DEAF_TO_SIGINT = "#!/bin/sh\ntrap '' INT\necho ready\nexec sleep 100\n"
# Ignores SIGINT and SIGTERM: only SIGKILL ends it.
STUBBORN = "#!/bin/sh\ntrap '' INT TERM\necho ready\nexec sleep 100\n"
# A node with a child process of its own.
PARENT = "#!/bin/sh\nsleep 100 &\necho child $!\nwait\n"


def child_lines(session) -> list[str]:
    """The lines of parent-1's log that name its child."""
    return [line for line in session.tail("parent-1") if line.startswith("child ")]


def session_for(prefix, write_launch, tmp_path, nodes: str, **kwargs) -> LaunchSession:
    path = write_launch("launch:\n" + textwrap.dedent(nodes).lstrip())
    kwargs.setdefault("stop_timeouts", (1.0, 1.0))
    return LaunchSession(path, env=prefix.env(), log_dir=tmp_path / "logs", backend="embedded", **kwargs)


def test_logs_are_captured_and_tailed(prefix, write_launch, tmp_path):
    prefix.add("chatty", CHATTY)
    screen = []
    session = session_for(
        prefix,
        write_launch,
        tmp_path,
        "- node: {pkg: demo, exec: chatty, name: talk, namespace: r1, output: screen}\n"
        "- node: {pkg: demo, exec: chatty, name: quiet}\n",
        on_line=lambda process, line: screen.append((process, line)),
    )
    with session:
        poll(
            lambda: "to stderr" in session.tail("talk") and "to stderr" in session.tail("quiet"),
            timeout=10,
            interval=0.05,
            what="both nodes' last line in their logs",
        )
        lines = session.tail("/r1/talk", 100)
        assert lines[0].startswith("started with --ros-args -r __node:=talk -r __ns:=/r1")
        assert lines[1:6] == [f"line {i}" for i in range(1, 6)]
        assert session.tail("chatty-1", 2) == ["line 5", "to stderr"]
        log_text = (tmp_path / "logs" / "chatty-1.log").read_text()
        assert "line 3\n" in log_text and "to stderr\n" in log_text
        assert "line 3\n" in (tmp_path / "logs" / "chatty-2.log").read_text()
    # Only output: screen is echoed, with its process name.
    assert ("chatty-1", "line 1") in screen
    assert not [entry for entry in screen if entry[0] == "chatty-2"]
    with pytest.raises(KeyError):
        session.tail("nobody")


def test_status_fields(prefix, write_launch, tmp_path):
    prefix.add("sleeper", SLEEPER)
    session = session_for(prefix, write_launch, tmp_path, "- node: {pkg: demo, exec: sleeper, name: s, namespace: n}\n")
    with session:
        time.sleep(0.2)
        (status,) = session.status()
        assert (status.name, status.fqn, status.state, status.restarts) == ("s", "/n/s", "running", 0)
        assert status.pid and pid_alive(status.pid) and status.exit_code is None
        assert status.uptime > 0 and status.cmd[0].endswith("lib/demo/sleeper")
        assert status.process == "sleeper-1" and status.ros  # a node of a package: a ROS node
        pid = status.pid
    (status,) = session.status()
    assert status.state == "stopped" and status.pid is None and not pid_alive(pid)


def test_a_plain_executable_is_no_ros_node(prefix, write_launch, tmp_path):
    prefix.add("sleeper", SLEEPER)
    session = session_for(prefix, write_launch, tmp_path, f"- executable: {{cmd: {prefix.root}/lib/demo/sleeper}}\n")
    with session:
        time.sleep(0.2)
        (status,) = session.status()
        assert (status.name, status.fqn, status.process, status.ros) == (None, None, "sleeper-1", False)


def test_respawn_after_sigkill_counts_restarts(prefix, write_launch, tmp_path):
    prefix.add("sleeper", SLEEPER)
    session = session_for(
        prefix, write_launch, tmp_path, "- node: {pkg: demo, exec: sleeper, name: s, respawn: 'true'}\n"
    )
    with session:
        first = session.status()[0].pid
        assert first is not None
        os.kill(first, signal.SIGKILL)
        status = poll(
            lambda: [s for s in session.status() if s.state == "running" and s.pid != first],
            timeout=10,
            interval=0.05,
            what="the node respawned after the first SIGKILL",
        )
        assert status[0].restarts == 1
        assert status[0].exit_code == -signal.SIGKILL  # running again, and still saying why it was restarted
        assert not pid_alive(first)
        second = status[0].pid
        assert second is not None
        os.kill(second, signal.SIGKILL)
        status = poll(
            lambda: [s for s in session.status() if s.state == "running" and s.pid != second],
            timeout=10,
            interval=0.05,
            what="the node respawned after the second SIGKILL",
        )
        assert status[0].restarts == 2


def test_respawn_waits_respawn_delay(prefix, write_launch, tmp_path):
    prefix.add("quitter", "#!/bin/sh\necho bye\nexit 3\n")
    # The delay leaves 0.7 s between the look 0.3 s into the backoff and the respawn: a test
    # process held up for a moment on a loaded machine must not see the respawn come early.
    session = session_for(
        prefix, write_launch, tmp_path, "- node: {pkg: demo, exec: quitter, respawn: 'true', respawn_delay: 1.0}\n"
    )
    with session:
        poll(
            lambda: session.status()[0].state,
            until=lambda state: state == "backoff",
            timeout=10,
            interval=0.05,
            what="the quitter in backoff",
        )
        assert session.status()[0].exit_code == 3
        assert not session.done()
        time.sleep(0.3)
        assert session.status()[0].restarts == 0
        poll(lambda: session.status()[0].restarts, until=lambda n: n >= 1, timeout=3, interval=0.05, what="a respawn")


def test_a_node_that_ended_says_how_how_often_and_its_last_words(prefix, write_launch, tmp_path):
    refusal = "parameter 'max_speed' = 9.0 is out of range"
    prefix.add("refuser", f'#!/bin/sh\necho starting\necho "{refusal}" >&2\nexit 2\n')
    session = session_for(
        prefix,
        write_launch,
        tmp_path,
        "- node: {pkg: demo, exec: refuser, name: controller, respawn: 'true', respawn_delay: 0.1}\n",
    )
    with session:
        status = poll(
            lambda: session.status()[0],
            until=lambda status: status.state == "backoff" and status.restarts >= 1,
            timeout=10,
            interval=0.02,
            what="the refuser respawned and ended again",
        )
        assert re.fullmatch(
            r"controller exited with code 2 \(restarted \d+ times?\): parameter 'max_speed' = 9.0 is out of range",
            status.problem,
        ), status.problem
    assert supervisor.ended_problem("composite-1", -9, 0) == "composite-1 was killed by SIGKILL"


def test_a_killed_nodes_routine_last_log_line_is_not_given_as_why(prefix, write_launch, tmp_path):
    """A node SIGKILLed said nothing of it: its last INFO line would read as the reason."""
    prefix.add("talker", "#!/bin/sh\necho '[INFO] [1.5] [robot1.safety]: clear'\nexec sleep 100\n")
    session = session_for(prefix, write_launch, tmp_path, "- node: {pkg: demo, exec: talker, name: safety}\n")
    with session:
        pid = poll(lambda: session.status()[0].pid, timeout=10, what="the talker started")
        assert pid is not None
        poll(lambda: any(": clear" in line for line in session.tail("safety")), timeout=10, what="its line")
        os.kill(pid, signal.SIGKILL)
        status = poll(lambda: session.status()[0], until=lambda s: s.state == "failed", timeout=10, what="it ended")
    assert status.problem == "safety was killed by SIGKILL"


def test_the_log_says_when_each_process_started_and_how_it_ended(prefix, write_launch, tmp_path):
    # As ros2 launch reports its processes; `fleet logs` then shows where one process of a node
    # ends and the next begins.  What the node printed (tail, status) leaves these lines out.
    prefix.add("quitter", '#!/bin/sh\necho "bye from $$"\nexit 3\n')
    session = session_for(
        prefix, write_launch, tmp_path, "- node: {pkg: demo, exec: quitter, respawn: 'true', respawn_delay: 0.1}\n"
    )
    with session:
        poll(lambda: session.status()[0].restarts, until=lambda n: n >= 3, timeout=10, interval=0.05, what="respawns")
        printed = session.tail("quitter-1", 3)
        assert len(printed) == 3 and all(line.startswith("bye from ") for line in printed), printed
    log = (tmp_path / "logs" / "quitter-1.log").read_text().splitlines()
    script = prefix.root / "lib" / "demo" / "quitter"
    for first in range(0, 6, 3):  # two whole processes: started, its line, died
        started, said, died = log[first : first + 3]
        pid = re.fullmatch(r"\[INFO\] \[[0-9.]+\] \[quitter-1\]: process started with pid \[(\d+)\]", started)
        assert pid, log
        assert said == f"bye from {pid[1]}", log
        assert died.startswith("[ERROR] "), log
        assert died.endswith(f"[quitter-1]: process has died [pid {pid[1]}, exit code 3, cmd: {script} --ros-args]"), (
            log
        )


def test_backoff_grows_exponentially():
    assert backoff_delay(2.0, 1) == 2.0
    assert backoff_delay(2.0, 2) == 4.0
    assert backoff_delay(2.0, 3) == 8.0
    assert backoff_delay(0.0, 1) == 0.0
    assert backoff_delay(0.0, 2) == MIN_BACKOFF * 2
    assert backoff_delay(1.0, 20) == MAX_BACKOFF
    assert backoff_delay(60.0, 5) == 60.0
    assert backoff_delay(1.0, 5000) == MAX_BACKOFF  # a node failing at once for hours: no overflow


def test_exit_without_respawn_is_final(prefix, write_launch, tmp_path):
    prefix.add("ok", "#!/bin/sh\necho done\n")
    prefix.add("bad", "#!/bin/sh\necho broken >&2\nexit 4\n")
    session = session_for(
        prefix,
        write_launch,
        tmp_path,
        "- node: {pkg: demo, exec: ok, name: ok}\n- node: {pkg: demo, exec: bad, name: bad}\n",
    )
    with session:
        assert session.wait(timeout=10)
        states = {status.name: (status.state, status.exit_code) for status in session.status()}
        assert states == {"ok": ("exited", 0), "bad": ("failed", 4)}
        assert [status.name for status in session.failed()] == ["bad"]
        assert session.tail("bad") == ["broken"]


def wakeups(thread) -> int:
    """How many times `thread` has gone to sleep and been woken (its voluntary context switches)."""
    status = Path(f"/proc/self/task/{thread.native_id}/status").read_text()
    return int(next(line.split()[1] for line in status.splitlines() if line.startswith("voluntary_ctxt_switches")))


def test_an_idle_session_sleeps_until_something_happens(prefix, write_launch, tmp_path):
    # An agent holds a session per robot: one that polled 20 times a second cost a core at 1,000.
    prefix.add("sleeper", SLEEPER)
    # c exits well after the idle second below, even when a loaded machine stretches that second.
    prefix.add("quits", "#!/bin/sh\nsleep 4\nexit 3\n")
    session = session_for(
        prefix,
        write_launch,
        tmp_path,
        "- node: {pkg: demo, exec: sleeper, name: a}\n"
        "- node: {pkg: demo, exec: sleeper, name: b}\n"
        "- node: {pkg: demo, exec: quits, name: c}\n",
    )
    with session:
        time.sleep(0.2)  # the thread settles into its first sleep
        before = wakeups(session._thread)
        time.sleep(1.0)
        # Polling at 20 Hz would be about 20.  A few are allowed: with two suites running at once,
        # 3 were counted once (c then exited 1.5 s after its start, possibly within this second).
        assert wakeups(session._thread) - before <= 5
        # ... and it still notices an exit at once.
        poll(lambda: session.failed(), timeout=10, interval=0.02, what="c's exit noticed")
        assert [(s.name, s.exit_code) for s in session.failed()] == [("c", 3)]


def test_stop_sends_sigterm_to_a_child_ignoring_sigint(prefix, write_launch, tmp_path):
    prefix.add("deaf", DEAF_TO_SIGINT)
    session = session_for(prefix, write_launch, tmp_path, "- node: {pkg: demo, exec: deaf}\n", stop_timeouts=(0.5, 5.0))
    session.start()
    poll(lambda: session.tail("deaf-1"), timeout=10, interval=0.05, what="deaf's first line")
    began = time.monotonic()
    session.stop()
    took = time.monotonic() - began
    assert 0.4 < took < 3.0
    assert session.status()[0].exit_code == -signal.SIGTERM


def test_stop_sends_sigkill_to_a_child_ignoring_sigterm(prefix, write_launch, tmp_path):
    prefix.add("stubborn", STUBBORN)
    session = session_for(
        prefix, write_launch, tmp_path, "- node: {pkg: demo, exec: stubborn}\n", stop_timeouts=(0.3, 0.5)
    )
    session.start()
    poll(lambda: session.tail("stubborn-1"), timeout=10, interval=0.05, what="stubborn's first line")
    pid = session.status()[0].pid
    assert pid is not None
    began = time.monotonic()
    session.stop()
    took = time.monotonic() - began
    assert 0.7 < took < 3.0
    assert session.status()[0].exit_code == -signal.SIGKILL
    assert not pid_alive(pid)


def test_stop_is_quick_for_well_behaved_nodes(prefix, write_launch, tmp_path):
    prefix.add("sleeper", SLEEPER)
    session = session_for(
        prefix,
        write_launch,
        tmp_path,
        "".join(f"- node: {{pkg: demo, exec: sleeper, name: s{i}}}\n" for i in range(5)),
        stop_timeouts=(5.0, 10.0),
    )
    session.start()
    began = time.monotonic()
    session.stop()
    assert time.monotonic() - began < 2.0
    assert {status.exit_code for status in session.status()} == {-signal.SIGINT}


def test_nothing_left_after_stop(prefix, write_launch, tmp_path):
    prefix.add("parent", PARENT)
    session = session_for(prefix, write_launch, tmp_path, "- node: {pkg: demo, exec: parent, respawn: 'true'}\n")
    session.start()
    line = poll(lambda: child_lines(session), timeout=10, interval=0.05, what="the parent to name its child")[0]
    child = int(line.split()[1])
    leader = session.status()[0].pid
    assert leader is not None
    assert set(group_members(leader)) >= {leader, child}
    session.stop()
    assert group_members(leader) == []
    assert not pid_alive(leader) and not pid_alive(child)


def test_restarting_a_session_leaves_no_inline_parameter_files_behind(prefix, write_launch, tmp_path):
    """An agent starts a new session over the same log directory at every restart and redeploy
    of a robot: each one's inline parameter files must go when it stops, or they pile up."""
    prefix.add("sleeper", SLEEPER)
    nodes = "- node: {pkg: demo, exec: sleeper, name: s, param: [{name: a, value: 1}, {name: b, value: 2}]}\n"
    params = tmp_path / "logs" / "params"
    for _ in range(5):
        session = session_for(prefix, write_launch, tmp_path, nodes)
        session.start()
        written = sorted(params.iterdir())
        assert len(written) == 2  # what its node reads, at its start and at each respawn
        assert all(str(path) in session.status()[0].cmd for path in written)
        session.stop()
        assert list(params.iterdir()) == []


def test_rcl_log_files_of_past_processes_do_not_pile_up(prefix, write_launch, tmp_path):
    """rcl writes a log file per process start into the session's ROS_LOG_DIR and never removes
    one: a node in a crash loop added one per respawn.  Before a process starts, the newest
    RCL_LOG_FILES_KEPT stay and older ones go."""
    prefix.add("sleeper", SLEEPER)
    ros = rcl_log_dir(tmp_path / "logs")
    ros.mkdir(parents=True)
    for index in range(RCL_LOG_FILES_KEPT + 10):  # as many earlier processes left
        old = ros / f"python3_{index}_1700000000000.log"
        old.write_text("x")
        os.utime(old, (1_700_000_000 + index, 1_700_000_000 + index))
    session = session_for(prefix, write_launch, tmp_path, "- node: {pkg: demo, exec: sleeper, name: s}\n")
    session.start()
    try:
        kept = sorted(path.name for path in ros.iterdir())
        assert len(kept) == RCL_LOG_FILES_KEPT
        assert kept == sorted(f"python3_{index}_1700000000000.log" for index in range(10, RCL_LOG_FILES_KEPT + 10))
    finally:
        session.stop()


def test_node_exit_kills_what_it_left_in_its_group(prefix, write_launch, tmp_path):
    prefix.add("parent", PARENT)
    session = session_for(prefix, write_launch, tmp_path, "- node: {pkg: demo, exec: parent}\n")
    with session:
        line = poll(lambda: child_lines(session), timeout=10, interval=0.05, what="the parent to name its child")[0]
        child = int(line.split()[1])
        pid = session.status()[0].pid
        assert pid is not None
        os.kill(pid, signal.SIGKILL)
        poll(lambda: pid_alive(child), until=lambda alive: not alive, timeout=5, interval=0.05, what="the child to end")


SUPERVISING_SCRIPT = """
import json, sys, time
from fleet.runtime.supervisor import LaunchSession
session = LaunchSession(sys.argv[1], log_dir=sys.argv[2], backend="embedded",
                        isolation=sys.argv[3])
session.start()
time.sleep(0.3)  # let the shells exec
print(json.dumps([status.pid for status in session.status()]), flush=True)
time.sleep(300)
"""


@pytest.mark.parametrize("isolation", ["process", "robot"])
def test_no_orphans_when_the_supervisor_is_sigkilled(prefix, write_launch, tmp_path, isolation):
    for exe in ("controller", "battery", "composite"):
        prefix.add(exe, SLEEPER, package="fleet_nodes")
    prefix.add("sleeper", SLEEPER)
    path = write_launch("""
        launch:
        - node: {pkg: demo, exec: sleeper, name: a}
        - node: {pkg: fleet_nodes, exec: controller, name: controller, namespace: r1}
        - node: {pkg: fleet_nodes, exec: battery, name: battery, namespace: r1}
    """)
    runner = subprocess.Popen(
        [sys.executable, "-c", SUPERVISING_SCRIPT, str(path), str(tmp_path / "logs"), isolation],
        env=prefix.env(),
        stdout=subprocess.PIPE,
        text=True,
    )
    assert runner.stdout is not None
    try:
        pids = set(json.loads(runner.stdout.readline()))
        assert len(pids) == (3 if isolation == "process" else 2)
        assert all(pid_alive(pid) for pid in pids)
        runner.kill()
        runner.wait(timeout=10)
        poll(
            lambda: [pid for pid in pids if pid_alive(pid)],
            until=lambda alive: not alive,
            timeout=5,
            interval=0.05,
            what="the supervisor's nodes to end",
        )
    finally:
        runner.kill()
        runner.wait()


def test_invalid_file_starts_nothing(prefix, write_launch, tmp_path):
    prefix.add("sleeper", SLEEPER)
    session = session_for(prefix, write_launch, tmp_path, "- node: {pkg: demo, exec: sleeper}\n- bogus: {}\n")
    with pytest.raises(LaunchFileError, match="unknown action 'bogus'"):
        session.start()
    assert session.status() == []
    session.stop()


def test_robot_isolation_shares_one_process(prefix, write_launch, tmp_path):
    prefix.add("composite", CHATTY, package="fleet_nodes")
    for exe in ("controller", "battery", "safety"):
        prefix.add(exe, SLEEPER, package="fleet_nodes")
    session = session_for(
        prefix,
        write_launch,
        tmp_path,
        """
        - group:
          - push_ros_namespace: {namespace: robot1}
          - node: {pkg: fleet_nodes, exec: controller, name: controller}
          - node: {pkg: fleet_nodes, exec: battery, name: battery}
          - node: {pkg: fleet_nodes, exec: safety, name: safety}
    """,
        isolation="robot",
    )
    with session:
        statuses = session.status()
        assert [status.fqn for status in statuses] == ["/robot1/controller", "/robot1/battery", "/robot1/safety"]
        assert len({status.pid for status in statuses}) == 1
        assert {status.process for status in statuses} == {"composite-1"}
        first = poll(lambda: session.tail("battery"), timeout=10, interval=0.05, what="the composite's first line")[0]
        assert first == (
            "started with --fleet-node controller --ros-args -r __node:=controller -r __ns:=/robot1 "
            "--fleet-node battery --ros-args -r __node:=battery -r __ns:=/robot1 "
            "--fleet-node safety --ros-args -r __node:=safety -r __ns:=/robot1"
        )


def test_bad_options_are_refused(prefix, write_launch, tmp_path):
    path = write_launch("launch: []\n")
    with pytest.raises(FleetError, match="isolation"):
        LaunchSession(path, isolation="thread")
    with pytest.raises(FleetError, match="backend"):
        LaunchSession(path, backend="docker")


# -- the ros2 backend, with a stand-in `ros2` command ----------------------------------------

FAKE_ROS2 = """\
#!/bin/sh
echo "fake ros2 $*"
exec sleep 100
"""


@pytest.fixture
def fake_ros2(tmp_path):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "ros2").write_text(FAKE_ROS2)
    (bin_dir / "ros2").chmod(0o755)
    return bin_dir


def test_ros2_backend_runs_ros2_launch(prefix, write_launch, tmp_path, fake_ros2):
    path = write_launch("launch: [{node: {pkg: demo, exec: anything_ros2_knows}}]\n")
    env = prefix.env(PATH=f"{fake_ros2}:{os.environ['PATH']}")
    session = LaunchSession(
        path, {"robot": "r1"}, env=env, log_dir=tmp_path / "logs", backend="auto", stop_timeouts=(1.0, 1.0)
    )
    with session:
        assert session.backend == "ros2"
        (status,) = session.status()
        assert status.cmd == [str(fake_ros2 / "ros2"), "launch", str(path), "robot:=r1"]
        line = poll(lambda: session.tail(status.process), timeout=10, interval=0.05, what="ros2's first line")[0]
        assert line == f"fake ros2 launch {path} robot:=r1"
        pid = status.pid
    assert pid is not None and not pid_alive(pid)


def test_the_check_before_ros2_launch_refuses_what_it_would_refuse_and_leaves_it_what_only_it_reads(
    prefix, write_launch, tmp_path, fake_ros2
):
    """An agent with `ros2` on PATH asks, before a deploy, whether ros2 launch could start a robot:
    a node whose executable is nowhere is refused there (it checked only that the file exists),
    and what only ros2 launch reads (an action, a substitution the embedded runner does not run)
    is left to it."""
    prefix.add("sleeper", SLEEPER)
    env = prefix.env(PATH=f"{fake_ros2}:{os.environ['PATH']}")

    def check(text: str) -> None:
        LaunchSession(write_launch(text), env=env, log_dir=tmp_path / "logs", backend="auto").check()

    with pytest.raises(LaunchFileError, match="executable 'nowhere' of package 'demo' not found"):
        check("launch: [{node: {pkg: demo, exec: nowhere}}]\n")
    check("launch: [{node: {pkg: demo, exec: sleeper}}]\n")
    check("launch: [{node: {pkg: demo, exec: sleeper, name: $(anon sleeper)}}, {shutdown: {}}]\n")
    assert not (tmp_path / "logs").exists()


def test_auto_with_robot_isolation_uses_embedded(prefix, write_launch, tmp_path, fake_ros2):
    prefix.add("sleeper", SLEEPER)
    path = write_launch("launch: [{node: {pkg: demo, exec: sleeper}}]\n")
    env = prefix.env(PATH=f"{fake_ros2}:{os.environ['PATH']}")
    with LaunchSession(path, env=env, log_dir=tmp_path / "logs", isolation="robot") as session:
        assert session.backend == "embedded"
    with pytest.raises(FleetError, match="needs the embedded backend"):
        LaunchSession(path, env=env, isolation="robot", backend="ros2").start()


def test_without_ros2_unsupported_files_are_refused_clearly(prefix, write_launch, tmp_path):
    path = write_launch("launch: [{shutdown: {}}]\n")
    env = prefix.env(PATH="/usr/bin:/bin")
    with pytest.raises(LaunchFileError) as caught:
        LaunchSession(path, env=env, log_dir=tmp_path / "logs").start()
    assert "action 'shutdown' needs the ros2 backend" in str(caught.value)
    assert "`ros2` is not on PATH" in str(caught.value)
    with pytest.raises(FleetError, match="needs the `ros2` command"):
        LaunchSession(path, env=env, backend="ros2").start()


def test_failed_respawn_does_not_take_the_others_down(prefix, write_launch, tmp_path):
    doomed = prefix.add("doomed", SLEEPER)
    prefix.add("sleeper", SLEEPER)
    session = session_for(
        prefix,
        write_launch,
        tmp_path,
        "- node: {pkg: demo, exec: doomed, respawn: 'true', respawn_delay: 0.3}\n- node: {pkg: demo, exec: sleeper}\n",
    )
    with session:
        doomed_pid, other_pid = [status.pid for status in session.status()]
        assert doomed_pid is not None and other_pid is not None
        doomed.unlink()
        os.kill(doomed_pid, signal.SIGKILL)
        poll(
            lambda: session.status()[0].state,
            until=lambda state: state == "failed",
            timeout=10,
            interval=0.05,
            what="doomed to fail",
        )
        assert "cannot respawn doomed-1" in session.tail("doomed-1")[-1]
        assert session.status()[1].state == "running" and pid_alive(other_pid)
