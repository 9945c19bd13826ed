"""The control server: the Zenoh router (with its registry of what was deployed where), the agent
that receives a fleet's desired state, persists it and runs its units through fleet.runtime, and
the local daemon (`fleet up`: a router and the agent `local` in one process).

Entry points: `fleet.server.agent.Agent`, `fleet.server.router.run_router`,
`python -m fleet.server.daemon`.  Imported module by module: the daemon's `-m` start stays lean.
"""
