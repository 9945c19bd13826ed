"""pytest plugin for multi-robot integration tests (fixtures land with issue 6)."""
