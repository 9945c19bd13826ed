"""`fleet status --watch` in a terminal: it redraws as the fleet changes (a robot deployed while
watching appears) and Ctrl-C ends it cleanly; with --json it streams a document a line."""

from __future__ import annotations

import json
import os
import pty
import queue
import select
import signal
import subprocess
import sys
import threading
import time

import pytest

pytestmark = pytest.mark.integration


class Terminal:
    """A command on a pseudo-terminal (rich redraws in place only on a terminal), its output kept."""

    def __init__(self, args: list[str], env: dict[str, str]):
        self.master, replica = pty.openpty()
        self.process = subprocess.Popen(
            args,
            env={**env, "COLUMNS": "160", "LINES": "50", "TERM": "xterm"},
            stdin=replica,
            stdout=replica,
            stderr=replica,
            start_new_session=True,
        )
        os.close(replica)
        self.output = ""

    def read_until(self, text: str, timeout: float) -> str:
        deadline = time.monotonic() + timeout
        while text not in self.output:
            left = deadline - time.monotonic()
            if left <= 0 or self.process.poll() is not None:
                raise AssertionError(f"{text!r} not shown within {timeout} s; screen so far:\n{self.output[-3000:]}")
            ready, _, _ = select.select([self.master], [], [], min(left, 0.2))
            if ready:
                try:
                    self.output += os.read(self.master, 65536).decode(errors="replace")
                except OSError:  # the command ended and closed the terminal
                    continue
        return self.output

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()
        os.close(self.master)


def test_status_watch_redraws_and_ends_on_ctrl_c(fresh_cluster):
    cluster = fresh_cluster
    cluster.start_router()
    cluster.start_agent("hostA")
    cluster.start_agent("hostB")
    cluster.wait_agents_online("hostA", "hostB")
    assert cluster.deploy(cluster.spec()).ok

    watch = Terminal(
        [sys.executable, "-m", "fleet", "status", "--watch", "--fleet", "tiny", "--connect", cluster.endpoint],
        cluster.env,
    )
    try:
        watch.read_until("robot3", 30)
        assert "robot4" not in watch.output
        robots = [{"name": "robot1"}, {"name": "robot2", "agent": "hostB"}, {"name": "robot3", "agent": "hostB"}]
        assert cluster.deploy(cluster.spec(robots=[*robots, {"name": "robot4", "agent": "hostB"}])).ok
        watch.read_until("robot4", 15)  # the redraw after the deploy

        watch.process.send_signal(signal.SIGINT)
        assert watch.process.wait(timeout=10) == 0
    finally:
        watch.close()


class PipedWatch:
    """`fleet status --watch ...` with its output into a pipe, read line by line with a bound."""

    def __init__(self, cluster, *options: str):
        command = ["status", "--watch", "--fleet", "tiny", "--connect", cluster.endpoint, *options]
        self.process = subprocess.Popen(
            [sys.executable, "-m", "fleet", *command], env=cluster.env, stdout=subprocess.PIPE, text=True
        )
        self.lines: queue.Queue[str] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.process.stdout or ():
            self.lines.put(line)

    def next_line(self, timeout: float = 20) -> str:
        try:
            return self.lines.get(timeout=timeout)
        except queue.Empty:
            raise AssertionError(f"nothing printed for {timeout} s while watching") from None

    def stop_on_ctrl_c(self) -> int:
        self.process.send_signal(signal.SIGINT)
        return self.process.wait(timeout=10)

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait()


def test_status_watch_json_streams_one_document_per_line_until_ctrl_c(fresh_cluster):
    cluster = fresh_cluster
    cluster.start_router()
    cluster.start_agent("hostA")
    cluster.wait_agents_online("hostA")
    assert cluster.deploy(cluster.spec(robots=[{"name": "robot1"}])).ok

    watch = PipedWatch(cluster, "--json")
    try:
        documents = [json.loads(watch.next_line()) for _ in range(3)]  # a refresh a line, as kubectl get -w
        assert [[row["name"] for row in document["robots"]] for document in documents] == [["robot1"]] * 3
        assert watch.stop_on_ctrl_c() == 0
    finally:
        watch.close()


def test_status_watch_into_a_pipe_prints_each_refresh_as_it_comes(fresh_cluster):
    """Piped (`| tee`, a file), the live display would show nothing until the end (and nothing at
    all when the watch is killed): each refresh is printed whole and flushed instead."""
    cluster = fresh_cluster
    cluster.start_router()
    cluster.start_agent("hostA")
    cluster.wait_agents_online("hostA")
    assert cluster.deploy(cluster.spec(robots=[{"name": "robot1"}])).ok

    watch = PipedWatch(cluster)
    try:
        blocks: list[list[str]] = [[]]
        while len(blocks) < 3:  # two refreshes read while the watch runs on
            line = watch.next_line()
            if line.strip():
                blocks[-1].append(line)
            else:
                blocks.append([])
        for block in blocks[:2]:
            assert block[0].startswith("Agents") and any(line.startswith("robot1 ") for line in block), block
        assert watch.stop_on_ctrl_c() == 0
    finally:
        watch.close()
