"""Which router a command without --connect reaches on this computer (fleet.wire.session.reaches):
it decides whether `fleet status` and `fleet down --all` point a user at a local daemon that
listens on another endpoint."""

from __future__ import annotations

import pytest

from fleet.wire.session import reaches


@pytest.mark.parametrize(
    "connect, listen, expected",
    [
        ("tcp/127.0.0.1:7447", "tcp/127.0.0.1:7447", True),
        ("tcp/127.0.0.1:7447", "tcp/0.0.0.0:7447", True),  # every address: loopback too
        ("tcp/localhost:7447", "tcp/[::]:7447", True),
        ("tcp/127.0.0.1:7447", "tcp/0.0.0.0:7448", False),  # another port
        ("tcp/127.0.0.1:7447", "tcp/127.0.0.1:7999", False),
        ("tls/127.0.0.1:7447", "tcp/0.0.0.0:7447", False),  # another protocol
        ("tcp/127.0.0.1:7447", "tcp/10.0.0.1:7447", False),  # one address, not loopback
        ("tcp/10.0.0.1:7447", "tcp/0.0.0.0:7447", False),  # not this computer's loopback: unknown
    ],
)
def test_a_client_reaches_a_router_on_the_same_port_and_protocol_of_its_addresses(connect, listen, expected):
    assert reaches(connect, listen) is expected
