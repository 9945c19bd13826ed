"""Helpers of the runtime tests: a throw-away ament prefix with small shell-script "nodes", and
whether a process is alive."""

from __future__ import annotations

import os
import textwrap
from pathlib import Path

import psutil

INDEX = Path("share") / "ament_index" / "resource_index" / "packages"


class FakePrefix:
    """An ament prefix under tmp_path; add executables to package `demo` (or others)."""

    def __init__(self, root: Path):
        self.root = root
        root.mkdir(parents=True, exist_ok=True)

    def add(self, executable: str, script: str, package: str = "demo") -> Path:
        (self.root / INDEX).mkdir(parents=True, exist_ok=True)
        (self.root / INDEX / package).touch()
        path = self.root / "lib" / package / executable
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(script).lstrip())
        path.chmod(0o755)
        return path

    def env(self, **extra: str) -> dict[str, str]:
        env = dict(os.environ)
        env["AMENT_PREFIX_PATH"] = str(self.root)
        env.update(extra)
        return env


def pid_alive(pid: int) -> bool:
    """True if `pid` is a live (non-zombie) process."""
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False
