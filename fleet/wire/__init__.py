"""The wire: what the control client and the control server share.

`protocol` (the Zenoh key space and versioned messages), `limits` (what an agent accepts; apart
so that `fleet render` checks them without importing pydantic), `session` (Zenoh session
configuration), `certificates` and `security` (TLS and access control of a fleet's network).
Imported module by module (certificates need the cryptography package).
"""
