"""fleet.testing as a user meets it: the plugin loads from the installed entry point in another
repository, a failing test's report carries the fleet's status, logs and a snapshot, and
nothing of its fleet outlives the run.  Plus the pure isolation helper."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import psutil
import pytest

from fleet.errors import SpecError
from fleet.expand import expand_fleet
from fleet.spec import load_spec
from fleet.testing import running_fleet
from fleet.testing.isolation import with_domain_id
from tests.e2e.e2e_helpers import SAFETY_STOP

pytestmark = pytest.mark.integration

USER_TEST = """
from pathlib import Path

SPEC = Path(__file__).parent / "fleets" / "safety_stop.yaml"


def test_scout_passes_the_crate(fleet_up):
    fleet = fleet_up(SPEC)
    fleet.wait_for(lambda: fleet.pose("scout").x > 3.0, sim_timeout=3, what="scout to pass the crate")
"""


def test_spec_gets_the_reserved_domain_and_stays_unchanged():
    spec = load_spec(SAFETY_STOP)
    isolated = with_domain_id(spec, 177)
    assert (spec.ros.domain_id, isolated.ros.domain_id) == (44, 177)
    assert expand_fleet(isolated).domain_id == 177
    assert isolated.source_file == spec.source_file and isolated.robots == spec.robots


def run_user_tests(tmp_path: Path, test_text: str) -> tuple[subprocess.CompletedProcess, Path]:
    """Run `test_text` with pytest in a repository of its own, as a fleet user does; returns the
    run and its --basetemp."""
    repo = tmp_path / "my_robots"
    (repo / "fleets").mkdir(parents=True)
    shutil.copy(SAFETY_STOP, repo / "fleets" / "safety_stop.yaml")
    (repo / "test_scout.py").write_text(test_text)
    basetemp = tmp_path / "basetemp"

    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")}
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-p",
            "no:cacheprovider",
            "-p",
            "no:xdist",
            f"--basetemp={basetemp}",
            "test_scout.py",
        ],
        cwd=repo,
        env=env,
        capture_output=True,
        text=True,
        timeout=240,
    )
    return done, basetemp


def test_a_failing_user_test_reports_status_logs_and_snapshot(tmp_path):
    done, basetemp = run_user_tests(tmp_path, USER_TEST)
    output = done.stdout + done.stderr
    assert done.returncode == 1, output
    assert "timed out waiting for scout to pass the crate" in output and "s of sim time (limit 3)" in output
    for section in ("status", "control plane", "node logs", "world"):
        assert f"fleet safety_stop: {section}" in output, output
    assert re.search(r"scout +local +running +3/3", output), output  # the status table
    assert "[scout.controller]: started:" in output  # a node's log
    # The report shows the last lines only; the whole logs outlive the fleet, for CI to keep.
    units = re.search(r"whole logs \(kept after the test\): (\S+)/<robot>/logs/", output)
    assert units, output
    assert "[scout.controller]: started:" in (Path(units.group(1)) / "scout" / "logs" / "controller.log").read_text()
    snapshot = re.search(r"snapshot: (\S+\.png)", output)
    assert snapshot and os.path.getsize(snapshot.group(1)) > 10_000, output

    # Nothing of the user's fleet is left: no process has its state directory any more.
    def of_that_run(process) -> bool:
        try:
            return process.environ().get("FLEET_STATE_DIR", "").startswith(str(basetemp))
        except psutil.Error:
            return False

    assert not [p.pid for p in psutil.process_iter() if of_that_run(p)]


USER_FIXTURE_TEST = """
from pathlib import Path

import pytest

SPEC = Path(__file__).parent / "fleets" / "safety_stop.yaml"


@pytest.fixture
def scout_past_the_crate(fleet_up):
    fleet = fleet_up(SPEC)
    fleet.wait_for(lambda: fleet.pose("scout").x > 3.0, sim_timeout=3, what="scout to pass the crate")
    return fleet


def test_scout_beyond(scout_past_the_crate):
    pass
"""


def test_a_user_fixture_failing_on_its_fleet_reports_it_too(tmp_path):
    """A fixture that brings the fleet up and waits on it fails in the test's setup: the report
    shows the fleet there as it does for a failing test body."""
    done, _ = run_user_tests(tmp_path, USER_FIXTURE_TEST)
    output = done.stdout + done.stderr
    assert done.returncode == 1 and "ERROR at setup of test_scout_beyond" in output, output
    for section in ("status", "control plane", "node logs", "world"):
        assert f"fleet safety_stop: {section}" in output, output


def test_running_fleet_removes_the_directory_it_made_once_the_fleet_ended_cleanly(tmp_path, monkeypatch):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # where running_fleet makes its own
    with running_fleet(SAFETY_STOP) as fleet:
        made = fleet.root
        assert made.parent == tmp_path and (made / "router.log").exists()
    assert not made.exists()

    # A failing body keeps it: the report printed names its logs.
    with pytest.raises(RuntimeError, match="on purpose"), running_fleet(SAFETY_STOP) as fleet:
        kept = fleet.root
        raise RuntimeError("on purpose")
    assert (kept / "router.log").exists()

    # A spec that never ran leaves nothing.
    with pytest.raises(SpecError), running_fleet(tmp_path / "missing.yaml"):
        pass
    assert list(tmp_path.iterdir()) == [kept]
