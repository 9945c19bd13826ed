"""Zenoh config files for a fleet on an untrusted network: mutual TLS and access rules.

`fleet certs` writes, beside the fleet's certificates (fleet.wire.certificates):
- router.json5: listens with TLS, demands a client certificate from the fleet's authority, and
  lets each agent's certificate (matched by its common name) reach only that agent's keys
  (protocol.agent_key_exprs) and query other agents' status, while operators' certificates reach every key of the fleet;
- agent-<name>.json5 and operator-<name>.json5: connect with that member's certificate.
Everything not allowed is denied.  The files are plain Zenoh configs: give them to
`--zenoh-config` (or FLEET_ZENOH_CONFIG); endpoints then use the `tls/` scheme.  They name the
certificates by file name alone: fleet reads a relative name from the config's own directory.
"""

from __future__ import annotations

import json
from pathlib import Path

from fleet.wire import certificates as certs
from fleet.wire import protocol as p

ROUTER = "router"
# Every message kind Zenoh's access control knows.
ALL_MESSAGES = [
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "declare_queryable",
    "reply",
    "liveliness_token",
    "declare_liveliness_subscriber",
    "liveliness_query",
]


def _tls(directory: Path, member: str, listen: bool) -> dict:
    # File names relative to the config, which lies beside them: fleet reads them from there
    # (fleet.wire.session.FILE_KEYS), so a computer's files can be copied anywhere together.
    own_key, own_cert = certs.key_path(directory, member).name, certs.cert_path(directory, member).name
    tls: dict = {"root_ca_certificate": certs.CA_CERT, "enable_mtls": True}
    if listen:
        tls.update(listen_private_key=own_key, listen_certificate=own_cert)
    tls.update(connect_private_key=own_key, connect_certificate=own_cert)
    return {"transport": {"link": {"tls": tls}}}


def access_rules(agents: list[str], operators: list[str]) -> dict:
    """Zenoh's access_control section, default deny.  An agent may send (ingress at the router)
    only on its own keys; what it may receive (egress) is any fleet key, because a query such as
    `fleet/*/status/**` is only allowed by a rule whose keys include it, and what reaches an agent
    is anyway only what matches the subscribers and queryables it was allowed to declare.
    Beyond its own keys, an agent may only query other agents' status (protocol.agent_asks_key_exprs):
    a deploy made while no agent was online names only the discovery host, and the others ask it
    for its address there; they may neither answer for it nor declare anything on its keys."""
    fleet_keys = ["fleet/**"]
    rules = [
        {
            "id": "operators",
            "messages": ALL_MESSAGES,
            "flows": ["ingress", "egress"],
            "permission": "allow",
            "key_exprs": fleet_keys,
        },
        {
            "id": "agents-receive",
            "messages": ALL_MESSAGES,
            "flows": ["egress"],
            "permission": "allow",
            "key_exprs": fleet_keys,
        },
        {
            "id": "agents-ask",
            "messages": ["query"],
            "flows": ["ingress"],
            "permission": "allow",
            "key_exprs": p.agent_asks_key_exprs(),
        },
    ]
    subjects: list[dict] = [{"id": "operators", "cert_common_names": operators}] if operators else []
    policies: list[dict] = [{"id": "operators", "rules": ["operators"], "subjects": ["operators"]}] if operators else []
    for agent in agents:
        rule = f"agent-{agent}"
        rules.append(
            {
                "id": rule,
                "messages": ALL_MESSAGES,
                "flows": ["ingress"],
                "permission": "allow",
                "key_exprs": p.agent_key_exprs(agent),
            }
        )
        subjects.append({"id": rule, "cert_common_names": [agent]})
        policies.append({"id": rule, "rules": [rule, "agents-receive", "agents-ask"], "subjects": [rule]})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects, "policies": policies}


def router_config(directory: Path, agents: list[str], operators: list[str]) -> dict:
    return {**_tls(directory, ROUTER, listen=True), "access_control": access_rules(agents, operators)}


def member_config(directory: Path, member: str) -> dict:
    return _tls(directory, member, listen=False)


def config_path(directory: Path, role: str, name: str = "") -> Path:
    return directory / (f"{role}-{name}.json5" if name else f"{role}.json5")


def configured_members(directory: Path, role: str) -> list[str]:
    """The names that have a config of `role` in `directory` (config_path's files)."""
    return sorted(path.name[len(role) + 1 : -len(".json5")] for path in directory.glob(f"{role}-*.json5"))


def write_config(path: Path, config: dict) -> None:
    path.write_text(json.dumps(config, indent=2) + "\n")
