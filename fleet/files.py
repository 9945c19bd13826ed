"""Writing files that other processes read while they change."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def write_atomic(path: str | Path, data: str | bytes, *, durable: bool = False, mode: int | None = None) -> None:
    """Replace `path` so readers see the old content or the new, never half of it (a temporary
    file in the same directory, renamed over it).

    durable: also flush the file and its directory to disk, for state that must survive a crash
    once it has been acknowledged (an agent's desired state, the router's registry).
    mode: permission bits of the new file (e.g. 0o755 for an executable).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "wb") as stream:
            stream.write(data.encode("utf-8") if isinstance(data, str) else data)
            if durable:
                stream.flush()
                os.fsync(stream.fileno())
        if mode is not None:
            os.chmod(temporary, mode)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    if durable:
        directory = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(directory)
        finally:
            os.close(directory)
