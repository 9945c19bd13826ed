"""Helpers for the runtime tests: a throw-away ament prefix with small shell-script "nodes"."""

from __future__ import annotations

import os
import textwrap
from collections.abc import Callable
from pathlib import Path

import pytest

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


@pytest.fixture
def prefix(tmp_path) -> FakePrefix:
    return FakePrefix(tmp_path / "prefix")


@pytest.fixture
def write_launch(tmp_path) -> Callable[[str, str], Path]:
    """write_launch(text, name='test.launch.yaml') -> path of the written launch file."""

    def write(text: str, name: str = "test.launch.yaml") -> Path:
        path = tmp_path / name
        path.write_text(textwrap.dedent(text).lstrip())
        return path

    return write
