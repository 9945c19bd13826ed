"""Starting and stopping the local daemon (`fleet up`, `fleet down --all`, a `fleet deploy` that
finds nobody listening): the process of fleet.server.daemon, run detached, its files in the
state directory (fleet.rules.state_dir)."""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from fleet.client.control_client import ControlClient, connect
from fleet.errors import ControlError
from fleet.rules import LOCAL_AGENT, daemon_log_file, daemon_pid_file, state_dir

START_TIMEOUT = 20.0
STOP_TIMEOUT = 30.0


def running_pid(root: Path) -> int | None:
    """The daemon's pid if its pid file names a live fleet daemon."""
    import psutil

    try:
        pid = int(daemon_pid_file(root).read_text().strip())
        process = psutil.Process(pid)
        if "fleet.server.daemon" in " ".join(process.cmdline()) and process.status() != psutil.STATUS_ZOMBIE:
            return pid
    except (OSError, ValueError, psutil.Error):
        pass
    return None


def start(listen: str, zenoh_config: Path | None = None, root: Path | None = None) -> int:
    """Start the daemon detached (or find it running); returns once its local agent answers."""
    root = root or state_dir()
    pid = running_pid(root)
    if pid is not None:
        return pid
    root.mkdir(parents=True, exist_ok=True)
    command = [sys.executable, "-m", "fleet.server.daemon", "--listen", listen, "--state-dir", str(root)]
    if zenoh_config is not None:
        command += ["--zenoh-config", str(zenoh_config)]
    with open(daemon_log_file(root), "ab") as log_file:
        process = subprocess.Popen(
            command,
            stdin=subprocess.DEVNULL,
            stdout=log_file,
            stderr=subprocess.STDOUT,
            start_new_session=True,
            close_fds=True,
        )
    daemon_pid_file(root).write_text(f"{process.pid}\n")
    if not _local_agent_answers(listen, zenoh_config, process, START_TIMEOUT):
        stop(root)
        raise ControlError(f"the local daemon did not come up on {listen}; see {daemon_log_file(root)}")
    return process.pid


def _local_agent_answers(listen: str, zenoh_config: Path | None, process, timeout: float) -> bool:
    from fleet.wire import protocol as p

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and process.poll() is None:
        try:
            with ControlClient([listen], zenoh_config) as client:
                while time.monotonic() < deadline and process.poll() is None:
                    for reply in client.session.get(p.agent_status_key("*", LOCAL_AGENT), timeout=1.0):
                        if reply.ok is not None:
                            return True
                    time.sleep(0.05)
        except ControlError:
            time.sleep(0.05)
    return False


def stop(root: Path | None = None) -> bool:
    """SIGTERM the daemon (it stops its robots first), SIGKILL after STOP_TIMEOUT."""
    import psutil

    root = root or state_dir()
    pid = running_pid(root)
    if pid is None:
        daemon_pid_file(root).unlink(missing_ok=True)
        return False
    process = psutil.Process(pid)
    process.terminate()
    try:
        process.wait(STOP_TIMEOUT)
    except psutil.TimeoutExpired:
        process.kill()
        process.wait(5)
    daemon_pid_file(root).unlink(missing_ok=True)
    return True


def connect_or_start(
    endpoint: str | None,
    zenoh_config: Path | None,
    needs_local: bool,
    announce: Callable[[str], None],
) -> ControlClient:
    """Connect; if nothing answers on the default endpoint (a loopback one, not an explicit
    `endpoint`) and `needs_local` (the spec places robots on the local agent), start the local
    daemon there first, after telling `announce`."""
    from fleet.wire.session import config_file, default_endpoint

    try:
        return connect(endpoint, zenoh_config)
    except ControlError:
        default = default_endpoint()
        on_loopback = any(host in default for host in ("/127.0.0.1:", "/localhost:", "/[::1]:"))
        if endpoint is not None or not on_loopback or not needs_local:
            raise
    announce(f"starting the local fleet daemon on {default} (state in {state_dir()})")
    start(default, config_file(zenoh_config))
    return connect(None, zenoh_config)
