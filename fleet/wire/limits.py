"""What an agent accepts: the limits of the control-plane messages and of the bundles in them.

Far above a real robot's launch description, far below what could hurt an agent.  Apart from
fleet.wire.protocol (which imports pydantic and builds every message model) so that
`fleet render` can refuse what an agent would refuse without paying for the whole protocol.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping

from fleet.rules import UNIT_OWN_NAMES

MAX_MESSAGE_BYTES = 8 * 1024 * 1024
MAX_FILE_BYTES = 1024 * 1024
MAX_FILES_PER_BUNDLE = 64
MAX_BUNDLES = 1024
MAX_LOG_LINES = 10_000

# A bundle file name is one plain path component: no separators, no `..`, nothing hidden.
_FILE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]{0,127}")


def check_file_name(name: str) -> str:
    """A bundle file name must stay inside the unit directory: one plain component."""
    if not isinstance(name, str) or not _FILE_NAME.fullmatch(name) or ".." in name:
        raise ValueError(f"file name {name!r} is not a plain file name (no '/', no '..', no leading '.')")
    if name in UNIT_OWN_NAMES:
        taken = ", ".join(sorted(UNIT_OWN_NAMES))
        raise ValueError(f"file name {name!r} is taken: the agent keeps {taken} in a unit's directory")
    return name


def files_problem(files: Mapping[str, str]) -> str | None:
    """Why an agent refuses a bundle of these files (too many, too large, a name that is not one
    plain file name), or None.  `fleet render` asks it too, so what renders is delivered."""
    if len(files) > MAX_FILES_PER_BUNDLE:
        return f"{len(files)} files, more than {MAX_FILES_PER_BUNDLE}"
    for name, text in files.items():
        try:
            check_file_name(name)
        except ValueError as error:
            return str(error)
        if len(text) * 4 > MAX_FILE_BYTES and len(text.encode()) > MAX_FILE_BYTES:  # UTF-8: at most 4 bytes a character
            return f"file {name!r} is larger than {MAX_FILE_BYTES} bytes"
    return None


def apply_size_bound(bundle_json_sizes: Iterable[int]) -> int:
    """At least the bytes of an ApplyRequest carrying bundles whose files, as JSON, have these
    sizes (with the `zenoh` transport, add the bridge routes' JSON): `fleet render` compares it
    with MAX_MESSAGE_BYTES without building the message."""
    return 4096 + sum(512 + size for size in bundle_json_sizes)  # the request's and each bundle's own fields
