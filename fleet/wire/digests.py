"""What a bundle's digests cover: the one rule shared by the expansion, which makes them
(fleet.expand.bundle), and the agent, which checks that a received bundle's digest is that of
its files before it compares digests to decide what to restart.  Apart from `protocol` so that
`fleet render` computes them without importing pydantic."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Collection, Mapping


def cold_json(entry: str, options: Mapping[str, object], files: Mapping[str, str], hot_files: Collection[str]) -> str:
    """The bundle without its hot files, as canonical JSON: what its digest hashes (a change here
    restarts the unit)."""
    cold = {name: text for name, text in sorted(files.items()) if name not in hot_files}
    return json.dumps({"entry": entry, "options": dict(sorted(options.items())), "files": cold}, sort_keys=True)


def digest_of(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


def hot_digest(files: Mapping[str, str], hot_files: Collection[str]) -> str:
    """Hash of the files applied in place: a change here needs a hot update, not a restart."""
    h = hashlib.sha256()
    for name in sorted(hot_files):
        h.update(name.encode() + b"\0" + files.get(name, "").encode() + b"\0")
    return h.hexdigest()
