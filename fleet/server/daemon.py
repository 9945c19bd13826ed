"""The embedded default: one background process with a router and the agent `local`.

`fleet up` (or a `fleet deploy` that finds nobody listening) starts it detached, `fleet down
--all` stops it (fleet.client.local_daemon).  Its files live in the state directory, laid out as
fleet.rules says.  Run in the foreground with
`python -m fleet.server.daemon --listen tcp/127.0.0.1:7447`.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from fleet.rules import LOCAL_AGENT, agent_dir, registry_file, router_dir, state_dir
from fleet.runtime.processes import stop_on_signals


def run(listen: str, root: Path, zenoh_config: Path | None) -> None:
    """The daemon itself: router session + registry, and the local agent connected to it."""
    from fleet.server.agent import Agent
    from fleet.server.router import Registry, serve_router
    from fleet.wire.session import open_router

    registry = Registry(registry_file(router_dir(root)))
    router_dir(root).mkdir(parents=True, exist_ok=True)
    agent = Agent(LOCAL_AGENT, [listen], agent_dir(root, LOCAL_AGENT), zenoh_config)
    stop_on_signals(agent.stop_event)
    with open_router([listen], zenoh_config) as router:
        entities = serve_router(router, registry)
        try:
            agent.run()
        finally:
            for entity in entities:
                entity.undeclare()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m fleet.server.daemon")
    parser.add_argument("--listen", default="tcp/127.0.0.1:7447")
    parser.add_argument("--state-dir", type=Path, default=None)
    parser.add_argument("--zenoh-config", type=Path, default=None)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    run(args.listen, args.state_dir or state_dir(), args.zenoh_config)
    return 0


if __name__ == "__main__":
    sys.exit(main())
