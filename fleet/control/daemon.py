"""The embedded default: one background process with a router and the agent `local`.

`fleet up` (or a `fleet deploy` that finds nobody listening) starts it detached; `fleet down
--all` stops it.  Its files live in the state directory, `$FLEET_STATE_DIR` or
`~/.local/state/fleet`:

    daemon.pid            pid of the daemon process
    daemon.log            its log (router and agent)
    router/registry.json  what was deployed where (see router.py)
    agents/local/         the local agent's desired state and units (see state.py)

Run in the foreground with `python -m fleet.control.daemon --listen tcp/127.0.0.1:7447`.
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from fleet.errors import ControlError

LOCAL_AGENT = "local"
STATE_VARIABLE = "FLEET_STATE_DIR"
START_TIMEOUT = 20.0
STOP_TIMEOUT = 30.0


def state_dir() -> Path:
    value = os.environ.get(STATE_VARIABLE)
    return Path(value).expanduser() if value else Path.home() / ".local" / "state" / "fleet"


def pid_file(root: Path) -> Path:
    return root / "daemon.pid"


def running_pid(root: Path) -> int | None:
    """The daemon's pid if its pid file names a live fleet daemon."""
    import psutil

    try:
        pid = int(pid_file(root).read_text().strip())
        process = psutil.Process(pid)
        if "fleet.control.daemon" in " ".join(process.cmdline()) and process.status() != psutil.STATUS_ZOMBIE:
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
    command = [sys.executable, "-m", "fleet.control.daemon", "--listen", listen, "--state-dir", str(root)]
    if zenoh_config is not None:
        command += ["--zenoh-config", str(zenoh_config)]
    with open(root / "daemon.log", "ab") as log_file:
        process = subprocess.Popen(
            command,
            stdin=subprocess.DEVNULL,
            stdout=log_file,
            stderr=subprocess.STDOUT,
            start_new_session=True,
            close_fds=True,
        )
    pid_file(root).write_text(f"{process.pid}\n")
    if not _local_agent_answers(listen, zenoh_config, process, START_TIMEOUT):
        stop(root)
        raise ControlError(f"the local daemon did not come up on {listen}; see {root / 'daemon.log'}")
    return process.pid


def _local_agent_answers(listen: str, zenoh_config: Path | None, process, timeout: float) -> bool:
    from fleet.control import protocol as p
    from fleet.control.client import ControlClient

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
        pid_file(root).unlink(missing_ok=True)
        return False
    process = psutil.Process(pid)
    process.terminate()
    try:
        process.wait(STOP_TIMEOUT)
    except psutil.TimeoutExpired:
        process.kill()
        process.wait(5)
    pid_file(root).unlink(missing_ok=True)
    return True


def run(listen: str, root: Path, zenoh_config: Path | None) -> None:
    """The daemon itself: router session + registry, and the local agent connected to it."""
    from fleet.control.agent import Agent
    from fleet.control.router import Registry, serve_router
    from fleet.control.session import open_router

    registry = Registry(root / "router" / "registry.json")
    (root / "router").mkdir(parents=True, exist_ok=True)
    agent = Agent(LOCAL_AGENT, [listen], root / "agents" / LOCAL_AGENT, zenoh_config)
    _stop_on_signals(agent.stop_event)
    with open_router([listen], zenoh_config) as router:
        entities = serve_router(router, registry)
        try:
            agent.run()
        finally:
            for entity in entities:
                entity.undeclare()


def _stop_on_signals(stop: threading.Event) -> None:
    def handler(signum, frame):
        stop.set()

    signal.signal(signal.SIGTERM, handler)
    signal.signal(signal.SIGINT, handler)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m fleet.control.daemon")
    parser.add_argument("--listen", default="tcp/127.0.0.1:7447")
    parser.add_argument("--state-dir", type=Path, default=None)
    parser.add_argument("--zenoh-config", type=Path, default=None)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    run(args.listen, args.state_dir or state_dir(), args.zenoh_config)
    return 0


if __name__ == "__main__":
    sys.exit(main())
