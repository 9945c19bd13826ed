"""Fixtures of the runtime tests (helpers in runtime_helpers.py)."""

from __future__ import annotations

import textwrap
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.runtime.runtime_helpers import FakePrefix


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
