"""A Bundle: everything one unit (a robot, or the world) needs to run, as flat files."""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from types import MappingProxyType
from typing import Any, Literal

from fleet.files import write_atomic
from fleet.wire.digests import cold_json, digest_of


@dataclass(frozen=True)
class Bundle:
    name: str  # robot name, or "world"
    kind: Literal["robot", "world"]
    agent: str
    entry: str  # the launch file to run, e.g. "robot1.launch.yaml"
    files: Mapping[str, str]  # flat file name -> text
    options: Mapping[str, str | bool] = field(default_factory=dict)  # e.g. {"isolation": "process"}
    hot_files: frozenset[str] = frozenset()  # applied in place on change, without a restart

    def __post_init__(self) -> None:
        object.__setattr__(self, "files", MappingProxyType(dict(self.files)))
        object.__setattr__(self, "options", MappingProxyType(dict(self.options)))

    @property
    def digest(self) -> str:
        """Equal digests mean the running unit needs no restart (hot files are left out)."""
        return digest_of(self._cold_json)

    @property
    def json_size(self) -> int:
        """At least the characters of its files as JSON (ASCII-escaped: never fewer than sent)."""
        hot = sum(len(name) + len(json.dumps(self.files[name])) + 4 for name in self.hot_files)
        return len(self._cold_json) + hot

    # Made once: a big fleet's files are tens of megabytes, and both the digest and the size of
    # a deploy message are asked of every bundle.  (A frozen dataclass has no setattr, but
    # cached_property writes the instance's __dict__ directly.)
    @cached_property
    def _cold_json(self) -> str:
        return cold_json(self.entry, self.options, self.files, self.hot_files)

    def to_json(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "kind": self.kind,
            "agent": self.agent,
            "entry": self.entry,
            "files": dict(self.files),
            "options": dict(self.options),
            "hot_files": sorted(self.hot_files),
            "digest": self.digest,
        }

    def write(self, directory: Path) -> None:
        """Write the files into `directory`, atomically: a running unit's processes may read them
        at any moment."""
        directory.mkdir(parents=True, exist_ok=True)
        for name, text in self.files.items():
            write_atomic(directory / name, text)
