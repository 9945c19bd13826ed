"""Starting and stopping the local daemon (`fleet up`, `fleet down --all`, a `fleet deploy` that
finds nobody listening): the process of fleet.server.daemon, run detached, its files in the
state directory (fleet.rules.state_dir)."""

from __future__ import annotations

import itertools
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from fleet.client.control_client import ControlClient, connect
from fleet.errors import ControlError
from fleet.rules import LOCAL_AGENT, daemon_agents, daemon_log_file, daemon_pid_file, state_dir

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


def _options(pid: int, flag: str) -> list[str]:
    """The values of `flag` on the daemon `pid`'s command line (as start() wrote it)."""
    import psutil

    try:
        argv = psutil.Process(pid).cmdline()
    except psutil.Error:
        return []
    return [value for option, value in itertools.pairwise(argv) if option == flag]


def running_agents(pid: int) -> list[str]:
    """The agents the daemon `pid` runs, from its command line."""
    return daemon_agents(_options(pid, "--agent"))


def running_endpoint(pid: int) -> str | None:
    """Where the daemon `pid` listens, from its command line."""
    return next(iter(_options(pid, "--listen")), None)


def agents_reached(endpoint: str) -> list[str]:
    """The agents of this computer's local daemon when `endpoint` is its router (none otherwise):
    they have the environment the daemon was started with, not the CLI's."""
    from fleet.wire.session import on_loopback

    pid = running_pid(state_dir())
    return running_agents(pid) if pid is not None and on_loopback(endpoint) else []


def start(
    listen: str | None,
    zenoh_config: Path | None,
    *,
    announce: Callable[[str], None],
    root: Path | None = None,
    agents: list[str] | tuple[str, ...] = (),
) -> int:
    """Start the daemon detached with `local` and `agents`, listening on `listen` with
    `zenoh_config` (or find it running so); returns once every one of its agents answers.

    None for `listen` or `zenoh_config`: as the running daemon has it; a new one listens on the
    default endpoint with $FLEET_ZENOH_CONFIG.  A daemon running without some of `agents`, on
    another endpoint or with another Zenoh config is started again as asked, after telling
    `announce`: its router and agents are one process.  Its fleets stay (the router keeps them
    on disk, and the agents start their robots again)."""
    from fleet.wire.session import config_file, default_endpoint

    root = root or state_dir()
    names = daemon_agents(agents)
    pid = running_pid(root)
    if pid is not None:
        runs = running_agents(pid)
        missing = [name for name in names if name not in runs]
        listened = running_endpoint(pid)
        configs = _options(pid, "--zenoh-config")
        configured = Path(configs[0]) if configs else None
        changes = []
        # Started again for any reason, it keeps the agents it runs (the robots they ran come back).
        names = daemon_agents([*runs, *missing])
        if missing:
            changes.append(f"with agents {', '.join(names)}")
        if listen is not None and listen != listened:
            changes.append(f"on {listen} (it listened on {listened})")
        if zenoh_config is not None and zenoh_config.resolve() != configured:
            changes.append(f"with the Zenoh config {zenoh_config.resolve()}")
        if not changes:
            return pid
        listen = listen or listened
        zenoh_config = zenoh_config or configured
        announce(
            f"restarting the local daemon (pid {pid}) {' and '.join(changes)}: the robots it runs stop and start again"
        )
        stop(root)
    listen = listen or default_endpoint()
    zenoh_config = zenoh_config or config_file(None)
    root.mkdir(parents=True, exist_ok=True)
    command = [sys.executable, "-m", "fleet.server.daemon", "--listen", listen, "--state-dir", str(root)]
    for name in names[1:]:  # `local` is the daemon's own
        command += ["--agent", name]
    if zenoh_config is not None:  # absolute: a restart may come from another directory
        command += ["--zenoh-config", str(zenoh_config.resolve())]
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
    if not _agents_answer(listen, zenoh_config, process, names, START_TIMEOUT):
        stop(root)
        raise ControlError(f"the local daemon did not come up on {listen}; see {daemon_log_file(root)}")
    return process.pid


def _agents_answer(listen: str, zenoh_config: Path | None, process, names: list[str], timeout: float) -> bool:
    from fleet.wire import protocol as p

    waiting = set(names)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and process.poll() is None:
        try:
            with ControlClient([listen], zenoh_config) as client:
                while time.monotonic() < deadline and process.poll() is None:
                    for name in sorted(waiting):
                        for reply in client.session.get(p.agent_status_key("*", name), timeout=1.0):
                            if reply.ok is not None:
                                waiting.discard(name)
                    if not waiting:
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


def elsewhere(endpoint: str | None) -> tuple[int, str] | None:
    """(pid, endpoint) of the local daemon when a command without --connect (`endpoint` None)
    would miss it: the default endpoint is a loopback one and it listens on another."""
    from fleet.wire.session import default_endpoint, on_loopback, reaches

    default = default_endpoint()
    pid = running_pid(state_dir()) if endpoint is None and on_loopback(default) else None
    where = running_endpoint(pid) if pid is not None else None
    return None if pid is None or where is None or reaches(default, where) else (pid, where)


def listening_elsewhere(endpoint: str | None) -> ControlError | None:
    """The error for a command that reached nothing there, when elsewhere() finds the daemon."""
    from fleet.wire.session import default_endpoint

    if (found := elsewhere(endpoint)) is None:
        return None
    pid, where = found
    return ControlError(
        f"no fleet router answers at {default_endpoint()}; the local daemon (pid {pid}) listens on {where}: "
        f"give --connect {where} (or set FLEET_CONNECT)"
    )


def connect_or_start(
    endpoint: str | None,
    zenoh_config: Path | None,
    agents: set[str],
    announce: Callable[[str], None],
    on_wait: Callable[[str], None] | None = None,
) -> ControlClient:
    """Connect; if nothing answers on the default endpoint (a loopback one, not an explicit
    `endpoint`) and the spec places robots on the local agent (one of `agents`), start the local
    daemon there first, after telling `announce`.  A spec for other agents is never started here
    by itself (its agents may be other computers): the error says how to run them on this one."""
    from fleet.wire.session import config_file, default_endpoint, on_loopback

    try:
        return connect(endpoint, zenoh_config, on_wait)
    except ControlError:
        default = default_endpoint()
        if endpoint is not None or not on_loopback(default):
            raise
        if moved := listening_elsewhere(endpoint):
            raise moved from None
        if LOCAL_AGENT not in agents:
            names = sorted(agents)
            raise ControlError(
                f"no fleet router answers at {default}, and this spec's agents are not `local`: to run them on "
                f"this computer, `fleet up {' '.join(f'--agent {name}' for name in names)}` first; on others, "
                "give their router with --connect (docs/multi-computer.md)"
            ) from None
    if running_pid(state_dir()) is None:
        announce(f"starting the local fleet daemon on {default} (state in {state_dir()})")
        start(default, config_file(zenoh_config), announce=announce)
    return connect(None, zenoh_config, on_wait)  # a daemon there still starting: its error if it fails
