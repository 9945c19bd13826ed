"""`fleet certs`: a fleet's certificate authority, its members' certificates and Zenoh configs."""

from __future__ import annotations

from pathlib import Path

import typer

from fleet.errors import FleetError, Location


def register(app: typer.Typer) -> None:
    app.command("certs")(certs)


def certs(
    spec: Path = typer.Argument(..., help="Fleet spec: its name and agents get certificates."),
    out: Path = typer.Option(..., "--out", "-o", help="Directory of the authority, certificates and configs."),
    router_address: list[str] = typer.Option(
        ["127.0.0.1", "localhost"], "--router-address", help="Address agents dial the router by (repeatable)."
    ),
    operator: list[str] = typer.Option(["operator"], "--operator", help="Name of a CLI user's certificate."),
    days: int = typer.Option(825, "--days", min=1, max=3650, help="Validity of new certificates."),
    json: bool = typer.Option(False, "--json", help="Print machine-readable JSON instead of a table."),
) -> None:
    """Create the fleet's certificates and Zenoh configs in OUT: mutual TLS, per-agent access rules.

    Creates (or completes) the fleet's certificate authority, a certificate
    for the router, each agent of SPEC and each operator, and the Zenoh
    configs that use them, with access rules letting each agent reach only
    its own keys.  Existing certificates are kept."""
    from fleet.cli.output import console, print_json
    from fleet.cli.render_cmd import load_and_expand
    from fleet.wire import certificates as c
    from fleet.wire import protocol as p
    from fleet.wire import security
    from fleet.wire.session import host_problem

    expansion = load_and_expand(spec, [])
    agents = sorted(set(expansion.spec.agents) | {bundle.agent for bundle in expansion.bundles})
    for name in operator:
        problem = p.key_name_problem(name)
        if problem or name in agents or name == security.ROUTER:
            why = problem or "is the name of an agent or the router"
            raise FleetError(f"--operator {name!r}: {why}")
    for address in router_address:  # it goes into the router's certificate, for agents to check
        if problem := host_problem(address):
            raise FleetError(f"--router-address: {problem}")
    if out.exists() and not out.is_dir():
        raise FleetError(f"{out}: not a directory")

    try:
        made, configs = _write_certificates(expansion.fleet, out, agents, operator, router_address, days)
    except OSError as error:  # OUT under a file, on a read-only disk, ...: said as render says it
        raise FleetError(f"cannot write {error.filename or out}: {error.strerror}", Location(out)) from None

    if json:
        print_json({"directory": str(out), "created": made, "configs": [str(path) for path in configs]})
        return
    router = security.config_path(out, security.ROUTER)
    console().print(
        f"fleet {expansion.fleet}: {_made_summary(made)} in {out}/, configs written\n"
        f"  router:   fleet router --listen tls/0.0.0.0:7447 --zenoh-config {router}\n"
        f"  agent:    fleet agent --name NAME --connect tls/ROUTER:7447 --zenoh-config {out}/agent-NAME.json5\n"
        f"  operator: fleet status --connect tls/ROUTER:7447 --zenoh-config {out}/operator-{operator[0]}.json5\n"
        "Keep ca.key off the robots: it signs new members."
    )
    router_cert = c.cert_path(out, security.ROUTER)
    if c.loopback_only(c.read_certificate(router_cert)):
        console().print(
            f"note: {router_cert} names only this computer (127.0.0.1, localhost): agents on other "
            "computers cannot verify the router. For them, give --router-address with the address "
            "they dial, into a new --out directory (an existing certificate is kept)."
        )


def _write_certificates(
    fleet: str, out: Path, agents: list[str], operator: list[str], router_address: list[str], days: int
) -> tuple[list[str], dict[Path, dict]]:
    """Complete the authority, certificates and configs in `out`: the names of the certificates
    made, and the configs written."""
    from fleet.wire import certificates as c
    from fleet.wire import security

    made: list[str] = []
    if not (out / c.CA_CERT).exists():
        c.create_authority(out, fleet)
        made.append(c.CA_CERT)
    authority = c.read_certificate(out / c.CA_CERT)
    if c.organization(authority) != fleet:
        held = c.organization(authority)
        raise FleetError(f"{out / c.CA_CERT}: the authority of fleet {held!r}, not {fleet!r}")
    members = [c.Member(security.ROUTER, server=True, addresses=tuple(router_address))]
    members += [c.Member(name) for name in agents + list(operator)]
    for member in members:
        if not c.cert_path(out, member.name).exists():
            c.issue(out, member, days=days)
            made.append(c.cert_path(out, member.name).name)

    # Operators made by an earlier run keep their access: a run names only those it adds.
    earlier = [name for name in security.configured_members(out, "operator") if name not in agents]
    operators = sorted({*operator, *earlier})
    configs = {security.config_path(out, security.ROUTER): security.router_config(out, agents, operators)}
    configs |= {security.config_path(out, "agent", name): security.member_config(out, name) for name in agents}
    configs |= {security.config_path(out, "operator", name): security.member_config(out, name) for name in operators}
    for path, config in configs.items():
        security.write_config(path, config)
    return made, configs


def _made_summary(made: list[str]) -> str:
    """What `certs` created: certificates (each with its key beside it), or that it kept them all."""
    if not made:
        return "no new certificate (all kept)"
    noun = "certificate" if len(made) == 1 else "certificates"
    return f"{len(made)} new {noun} with their keys ({', '.join(made)})"
