"""The embedded default: one background process with a router and the agent `local`.

`fleet up` (or a `fleet deploy` that finds nobody listening) starts it detached, `fleet down
--all` stops it (fleet.client.local_daemon).  `fleet up --agent NAME` adds agents of other
names, so that a spec written for several computers (fleets/warehouse_ten.yaml) runs on this one.
Its files live in the state directory, laid out as fleet.rules says.  Run in the foreground with
`python -m fleet.server.daemon --listen tcp/127.0.0.1:7447 [--agent NAME ...]`.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from fleet.rules import agent_dir, daemon_agents, registry_file, router_dir, state_dir
from fleet.runtime.processes import stop_on_signals


def run(listen: str, root: Path, zenoh_config: Path | None, extra_agents: list[str] | tuple[str, ...] = ()) -> None:
    """The daemon itself: router session + registry, and its agents connected to it (`local` on
    the main thread, the others each on a thread of its own, all stopped by one signal)."""
    import threading

    from fleet.server.agent import Agent
    from fleet.server.router import Registry, serve_router
    from fleet.wire.session import open_router, router_config

    root = root.resolve()  # its agents change the working directory (fleet.server.agent)
    registry = Registry(registry_file(router_dir(root)))
    router_dir(root).mkdir(parents=True, exist_ok=True)
    local, *others = [
        Agent(name, [listen], agent_dir(root, name), zenoh_config) for name in daemon_agents(extra_agents)
    ]
    stop = stop_on_signals(local.stop_event)
    for agent in others:
        agent.stop_event = stop  # one of them ending (a fault) ends the daemon, not just itself
    threads = [threading.Thread(target=agent.run, name=f"fleet-agent-{agent.name}") for agent in others]
    with open_router(router_config([listen], zenoh_config)) as router:
        entities = serve_router(router, registry)
        try:
            for thread in threads:
                thread.start()
            local.run()
        finally:
            stop.set()
            for thread in threads:
                thread.join()
            for entity in entities:
                entity.undeclare()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m fleet.server.daemon")
    parser.add_argument("--listen", default="tcp/127.0.0.1:7447")
    parser.add_argument("--state-dir", type=Path, default=None)
    parser.add_argument("--zenoh-config", type=Path, default=None)
    parser.add_argument("--agent", action="append", default=[], help="another agent to run (repeatable)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    run(args.listen, args.state_dir or state_dir(), args.zenoh_config, args.agent)
    return 0


if __name__ == "__main__":
    sys.exit(main())
