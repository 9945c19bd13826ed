"""The embedded runner starts what real launch_ros (Jazzy) starts, for every corpus file.

expected/*.json was recorded by record_launch_ros.py under real launch_ros; here the same
corpus runs under the embedded runner with the same recorder (probe.py) as its executables, and
what the recorder wrote must be the same: argv, parameter file contents, environment added or
removed, process names.  A file launch_ros refuses must be refused too.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from fleet.errors import FleetError
from fleet.runtime.supervisor import LaunchSession
from tests.conformance.prefix import PACKAGE, base_env, corpus_files, expected, launch_args, make_prefix, normalise

FILES = corpus_files()


def test_the_corpus_is_large_and_recorded():
    assert len(FILES) >= 40
    for path in FILES:
        assert expected(path)  # every corpus file has its recorded result


def run_embedded(path: Path, tmp_path: Path) -> dict:
    prefix = make_prefix(tmp_path / "prefix")
    records = tmp_path / "records"
    records.mkdir()
    env = base_env(prefix, records)
    arguments = dict(item.split(":=", 1) for item in launch_args(path))
    session = LaunchSession(
        prefix / "share" / PACKAGE / "launch" / path.name,
        launch_args=arguments,
        env=env,
        log_dir=tmp_path / "logs",
        backend="embedded",
        stop_timeouts=(2.0, 2.0),
    )
    try:
        session.start()
    except FleetError:
        return {"fails": True}
    try:
        assert session.plan is not None
        wanted = len(session.plan.nodes)
        deadline = time.monotonic() + 20.0
        while len(list(records.glob("*.json"))) < wanted and time.monotonic() < deadline:
            time.sleep(0.02)
        names = {status.pid: status.process for status in session.status() if status.pid is not None}
    finally:
        session.stop()
    return {"processes": normalise(records, names, prefix, env)}


@pytest.mark.parametrize("path", FILES, ids=[path.name for path in FILES])
def test_embedded_runner_starts_what_launch_ros_starts(path, tmp_path):
    assert run_embedded(path, tmp_path) == expected(path)
