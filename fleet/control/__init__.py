"""The Zenoh control plane: protocol, session configuration, router, agent, client, local daemon.

Only this package imports zenoh; the CLI imports it inside command bodies.
"""
