"""Zenoh session configuration for the router, the agents and the CLI.

Our settings: explicit endpoints (never every interface), multicast scouting and gossip off
(peers are found through the configured router only), a short link lease on agents so a dead
agent disappears quickly.  Security (TLS, mutual TLS, user/password, access control) is not coded
here: it comes from a Zenoh JSON5 config file given with --zenoh-config or FLEET_ZENOH_CONFIG.
That file is the base; our settings are added where it leaves them unset, command-line
endpoints always win, and the mode is always the process's role.
"""

from __future__ import annotations

import contextlib
import ipaddress
import json
import logging
import os
import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from fleet.errors import COMMAND_LINE, ControlError, FleetError, Location

if TYPE_CHECKING:
    import threading

    import zenoh

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
ENDPOINT_VARIABLE = "FLEET_CONNECT"
CONFIG_VARIABLE = "FLEET_ZENOH_CONFIG"
AGENT_LEASE_MS = 2000  # link lease of agents: a frozen agent is dropped after 2 s (default 10 s)
ROUTER_LEASE_MS = 2000
RETRY_MAX_DELAY = 2.0  # daemons retry opening their session at least this often
RETRY_LOG_PERIOD = 30.0  # and say again that they cannot, this often (at once when the reason changes)

log = logging.getLogger("fleet.session")


# Zenoh's endpoint form: PROTOCOL/ADDRESS[?METADATA][#CONFIG]; the IP protocols' address is HOST:PORT.
_ENDPOINT = re.compile(r"(?P<protocol>[a-z][a-z0-9-]*)/(?P<address>[^?#]+)(?:\?[^#]*)?(?:#.*)?")
_IP_PROTOCOLS = frozenset({"tcp", "udp", "tls", "quic", "ws"})
_HOST_NAME = re.compile(
    r"(?=.{1,253}$)[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?(\.[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?)*"
)
EXAMPLE = "tcp/10.0.0.1:7447"


def endpoint_parts(endpoint: str) -> tuple[str, str, str] | None:
    """PROTOCOL/HOST:PORT -> (protocol, host, port), metadata and config left out ("" for a part
    not written); None when `endpoint` is not of Zenoh's endpoint form."""
    match = _ENDPOINT.fullmatch(endpoint)
    if match is None:
        return None
    host, colon, port = match["address"].rpartition(":")
    return match["protocol"], host, port if colon else ""


def endpoint_problem(endpoint: str) -> str | None:
    """Why `endpoint` is not a Zenoh endpoint fleet can use, or None (port 0: any free port)."""
    parts = endpoint_parts(endpoint)
    if parts is None:
        return f"endpoint {endpoint!r} is not PROTOCOL/HOST:PORT (such as {EXAMPLE})"
    protocol, host, port = parts
    if protocol not in _IP_PROTOCOLS:
        return None  # unix sockets, serial lines, ...: Zenoh checks its own
    if not port.isdigit() or int(port) > 65535:
        return f"endpoint {endpoint!r} has no port from 0 to 65535 (such as {EXAMPLE})"
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    elif ":" in host and host_problem(host) is None:  # an IPv6 address; anything else is no host
        return f"endpoint {endpoint!r}: an IPv6 address goes in brackets ({protocol}/[{host}]:{port})"
    problem = host_problem(host)
    return f"endpoint {endpoint!r}: {problem}" if problem else None


def host_problem(host: str) -> str | None:
    """Why `host` is not a host name, an IPv4 or an IPv6 address, or None."""
    try:
        if ":" in host:
            ipaddress.IPv6Address(host)
        elif re.fullmatch(r"[0-9.]+", host):
            ipaddress.IPv4Address(host)
        elif not _HOST_NAME.fullmatch(host):
            return f"{host!r} is not a host name or an IP address"
    except ValueError:
        return f"{host!r} is not an IP address"
    return None


def listen_problem(endpoint: str) -> str | None:
    """Why this computer cannot listen on `endpoint` (not an endpoint, or its host is not one of
    this computer's addresses), or None.  Whether its port is free shows only on listening."""
    if problem := endpoint_problem(endpoint):
        return problem
    import socket

    protocol, host, _ = endpoint_parts(endpoint) or ("", "", "")
    if protocol not in _IP_PROTOCOLS:
        return None
    host = host.strip("[]")
    try:
        for family, kind, _, _, address in socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM):
            with socket.socket(family, kind) as probe:
                probe.bind(address)
    except OSError as error:
        return f"endpoint {endpoint!r}: this computer cannot listen on {host} ({error.strerror or error})"
    return None


def on_loopback(endpoint: str) -> bool:
    """Whether `endpoint` names this computer's loopback (a router only this computer reaches)."""
    parts = endpoint_parts(endpoint)
    return parts is not None and parts[1] in ("127.0.0.1", "localhost", "[::1]")


def reaches(connect: str, listen: str) -> bool:
    """Whether a client connecting to `connect` reaches a router listening on `listen`, both on
    this computer: the same endpoint, or a loopback one and `listen` on every address."""
    if connect == listen:
        return True
    mine, theirs = endpoint_parts(connect), endpoint_parts(listen)
    return (
        mine is not None
        and theirs is not None
        and mine[0::2] == theirs[0::2]
        and on_loopback(connect)
        and theirs[1] in ("0.0.0.0", "[::]")
    )


def _checked(endpoints: list[str]) -> list[str]:
    for endpoint in endpoints:
        if problem := endpoint_problem(endpoint):
            raise FleetError(problem, Location(COMMAND_LINE))
    return endpoints


def default_endpoint() -> str:
    return os.environ.get(ENDPOINT_VARIABLE) or DEFAULT_ENDPOINT


def config_file(explicit: str | Path | None) -> Path | None:
    value = explicit or os.environ.get(CONFIG_VARIABLE)
    if not value:
        return None
    path = Path(value).expanduser()
    if not path.is_file():
        raise FleetError(
            "a directory, not a Zenoh config file" if path.is_dir() else "no such Zenoh config file", Location(path)
        )
    return path


# The keys of a Zenoh config that name files.  Zenoh reads a relative name from the working
# directory, which an agent leaves for its state directory as daemons do; fleet reads it from the
# config file's directory instead (as kubectl reads a kubeconfig's), so that a computer's config
# and certificates work from wherever they were copied, whatever directory a command runs in.
_TLS = "transport/link/tls/"
FILE_KEYS = (
    f"{_TLS}root_ca_certificate",
    f"{_TLS}listen_certificate",
    f"{_TLS}listen_private_key",
    f"{_TLS}connect_certificate",
    f"{_TLS}connect_private_key",
    "transport/auth/usrpwd/dictionary_file",
)


def _base_config(user_config: Path | None):
    import zenoh

    if user_config is None:
        return zenoh.Config()
    try:
        config = zenoh.Config.from_file(str(user_config))
    except Exception as error:  # zenoh raises ZError with the parser's message
        problem, line, column = config_parse_problem(str(error))
        raise FleetError(f"invalid Zenoh config: {problem}", Location(user_config, line, column)) from None
    _read_files_beside(config, Path(os.path.abspath(user_config)).parent)  # lexical, as kubectl's
    try:
        _check_tls_files(config)
    except FleetError as error:  # a certificate's problem, at the place of the config that names it
        raise FleetError(error.message, Location(user_config)) from None
    return config


# How Zenoh's parsers say where a config is wrong, and where in Zenoh's source it noticed.
_CONFIG_PLACES = (
    re.compile(
        r'JSON error: Message \{ msg: "(?P<problem>.*)", '
        r"location: Some\(Location \{ line: (?P<line>\d+), column: (?P<column>\d+) \}\) \}",
        re.S,
    ),
    re.compile(r'YAML error: Error\("(?P<problem>.*)", line: (?P<line>\d+), column: (?P<column>\d+)\)', re.S),
    re.compile(r"\s*--> (?P<line>\d+):(?P<column>\d+)\n.*\n\s*= (?P<problem>[^\n]*)", re.S),  # JSON5 syntax
)
_RUST_SOURCE = re.compile(r" at \S+\.rs:\d+\.?$")


def config_parse_problem(message: str) -> tuple[str, int | None, int | None]:
    """(problem, line, column) of Zenoh's message about a config file it cannot read: the place
    in the file, not a caret drawn over several lines or the place in Zenoh's Rust source."""
    message = _RUST_SOURCE.sub("", message.strip())
    for pattern in _CONFIG_PLACES:
        if match := pattern.fullmatch(message):
            problem = re.sub(r"\\(.)", r"\1", match["problem"])  # Rust's Debug escapes of the quoted text
            return problem, int(match["line"]), int(match["column"])
    return message, None, None


def _read_files_beside(config, directory: Path) -> None:
    for key in FILE_KEYS:
        name = json.loads(config.get_json(key))
        if isinstance(name, str) and name:
            config.insert_json5(key, json.dumps(str(directory / Path(name).expanduser())))


def _check_tls_files(config) -> None:
    """Say which certificate is unusable and why, before Zenoh fails a handshake naming none."""
    from fleet.wire.certificates import check_certificate, check_key

    def named(key: str) -> Path | None:
        name = json.loads(config.get_json(_TLS + key))
        return Path(name) if name else None

    authority = named("root_ca_certificate")
    if authority is not None:
        check_certificate(authority, None)
    for role in ("listen", "connect"):
        if certificate := named(f"{role}_certificate"):
            check_certificate(certificate, authority)
        if key := named(f"{role}_private_key"):
            check_key(key)


def check_identity(name: str, user_config: Path | None) -> None:
    """Refuse (FleetError) an agent `name` that is not the common name of the client certificate
    its Zenoh config names: the router's access rules know an agent by that name only, and would
    deny it every key of its own."""
    from fleet.wire.certificates import common_name, read_certificate

    if user_config is None:
        return
    path = json.loads(_base_config(user_config).get_json("transport/link/tls/connect_certificate"))
    if not path:
        return
    identity = common_name(read_certificate(Path(path)))
    if identity != name:
        raise FleetError(
            f"agent name {name!r} is not the name in its certificate {path} ({identity!r})", Location("--name")
        )


def _set_unless_user_set(config, key: str, value) -> None:
    """Insert our value where the user's file left the built-in default."""
    import zenoh

    if config.get_json(key) == zenoh.Config().get_json(key):
        config.insert_json5(key, json.dumps(value))


_RUNTIME_VARIABLE = "ZENOH_RUNTIME"


@contextlib.contextmanager
def _zenoh_runtime(runtime: str | None) -> Iterator[None]:
    """Zenoh reads ZENOH_RUNTIME (its threads) once, when a process opens its first session:
    `runtime` is set while a session opens, and not left for the processes this one starts (nodes
    on rmw_zenoh would read it too).  A user's own setting wins."""
    if runtime is None or _RUNTIME_VARIABLE in os.environ:
        yield
        return
    os.environ[_RUNTIME_VARIABLE] = runtime
    try:
        yield
    finally:
        os.environ.pop(_RUNTIME_VARIABLE, None)


ROUTER_QUEUE_BATCHES = 16


def router_config(listen: list[str], user_config: Path | None = None):
    config = _base_config(user_config)
    config.insert_json5("mode", '"router"')
    if listen:
        config.insert_json5("listen/endpoints", json.dumps(_checked(listen)))
    else:
        _set_unless_user_set(config, "listen/endpoints", [DEFAULT_ENDPOINT])
    _common(config, ROUTER_LEASE_MS)
    # 64 KiB batches queued towards each member (Zenoh's default: 2): the `zenoh` transport's
    # bursts wait there while a busy computer's scheduler is late, instead of being dropped after
    # 1 ms.  The wait before a drop stays Zenoh's: a dead link must not hold up the router.
    _set_unless_user_set(config, "transport/link/tx/queue/size/data", ROUTER_QUEUE_BATCHES)
    return config


def router_listens(config) -> list[str]:
    """The endpoints a router_config listens on (the user's file's when no endpoint was given)."""
    endpoints = json.loads(config.get_json("listen/endpoints"))
    if isinstance(endpoints, dict):  # Zenoh's per-mode form, {router: [...], peer: [...]}
        endpoints = endpoints.get("router", [])
    return [str(endpoint) for endpoint in endpoints]


def client_config(
    connect: list[str], user_config: Path | None = None, lease_ms: int | None = None, settings: dict | None = None
):
    """`settings`: Zenoh config keys -> values this client uses unless the user's file sets them."""
    config = _base_config(user_config)
    config.insert_json5("mode", '"client"')
    if connect:
        config.insert_json5("connect/endpoints", json.dumps(_checked(connect)))
    else:
        _set_unless_user_set(config, "connect/endpoints", [default_endpoint()])
    _common(config, lease_ms)
    # Daemons (agents) reconnect when the router comes back: try every second at most, not
    # Zenoh's default back-off to 4 s, so `fleet status` works again soon after a router restart.
    if lease_ms is not None:
        _set_unless_user_set(
            config, "connect/retry", {"period_init_ms": 250, "period_max_ms": 1000, "period_increase_factor": 2}
        )
    for key, value in (settings or {}).items():
        _set_unless_user_set(config, key, value)
    return config


def _common(config, lease_ms: int | None) -> None:
    _set_unless_user_set(config, "scouting/multicast/enabled", False)
    _set_unless_user_set(config, "scouting/gossip/enabled", False)
    # Control messages are small; shared-memory segments would only be left in /dev/shm by
    # killed processes.
    _set_unless_user_set(config, "transport/shared_memory/enabled", False)
    if lease_ms is not None:
        _set_unless_user_set(config, "transport/link/tx/lease", lease_ms)


def open_client(
    connect: list[str],
    user_config: Path | None = None,
    lease_ms: int | None = None,
    settings: dict | None = None,
    runtime: str | None = None,
) -> zenoh.Session:
    """Open a client session or raise ControlError (router unreachable or credentials refused).
    `runtime`: the process's ZENOH_RUNTIME, if this is its first session (else Zenoh's default)."""
    import zenoh

    config = client_config(connect, user_config, lease_ms, settings)
    try:
        with _zenoh_runtime(runtime):
            return zenoh.open(config)
    except zenoh.ZError as error:
        endpoints = json.loads(config.get_json("connect/endpoints"))
        where = ", ".join(endpoints)
        raise ControlError(
            f"cannot reach the fleet router at {where}: {_first_line(error)} ({_hint(config, endpoints)})"
        ) from None


def _hint(config, endpoints: list[str]) -> str:
    if any(endpoint.startswith("tls/") for endpoint in endpoints):
        if not json.loads(config.get_json("transport/link/tls/connect_certificate")):
            return (
                "no client certificate: a router made with `fleet certs` refuses TLS clients without one; "
                f"give a member's config with --zenoh-config or ${CONFIG_VARIABLE}"
            )
        return "is it running? is its certificate issued by the same authority, for the address dialled?"
    credentials = f"if it requires credentials or TLS, give them with --zenoh-config or ${CONFIG_VARIABLE}"
    if all(on_loopback(endpoint) for endpoint in endpoints):
        return f"is it running? on this computer `fleet up` starts it, as `fleet deploy` does; {credentials}"
    return f"is it running? {credentials}"


def open_client_retrying(
    connect: list[str],
    user_config: Path | None,
    lease_ms: int | None,
    stop: threading.Event,
    settings: dict | None = None,
    runtime: str | None = None,
) -> zenoh.Session | None:
    """For daemons: retry until the router answers (or `stop` is set, then None).  The first
    failure is logged at once, then again when its reason changes or every RETRY_LOG_PERIOD s."""
    delay = 0.2
    said, said_at = "", 0.0
    while not stop.is_set():
        try:
            session = open_client(connect, user_config, lease_ms, settings, runtime)
        except ControlError as error:
            reason = str(error)
            if reason != said or time.monotonic() - said_at >= RETRY_LOG_PERIOD:
                log.warning("%s; retrying every %.0f s", reason, RETRY_MAX_DELAY)
                said, said_at = reason, time.monotonic()
            stop.wait(delay)
            delay = min(delay * 2, RETRY_MAX_DELAY)
        else:
            if said:
                log.info("reached the fleet router at %s", ", ".join(connect))
            return session
    return None


def open_router(config):
    """A router's session on a router_config."""
    import zenoh

    try:
        return zenoh.open(config)
    except zenoh.ZError as error:
        where = ", ".join(router_listens(config))
        raise ControlError(f"cannot start the router on {where}: {_first_line(error)}") from None


def _first_line(error: Exception) -> str:
    text = str(error)
    # zenoh appends " at /root/.cargo/...rs:NNN." to its messages: not for users.
    cut = text.find(" at /")
    return (text[:cut] if cut > 0 else text).strip()
