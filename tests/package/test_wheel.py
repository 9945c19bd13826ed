"""fleet as a user installs it: a wheel built from the sources, installed into a fresh virtual
environment (its dependencies from the package index, nothing borrowed from this one), run from
a directory outside the checkout: `fleet render` and a short `fleet deploy` of two_robots."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import psutil
import pytest
import yaml

from fleet.testing.isolation import free_tcp_port
from fleet.testing.processes import MARKER_VARIABLE

REPO = Path(__file__).resolve().parents[2]
# What the wheel is built from; anything else of the checkout must not be needed at run time.
SOURCES = ("pyproject.toml", "README.md", "fleet", "templates")
INSTALL_TIMEOUT = 600  # s: about a minute on a quiet machine (the ROS wheels are big)
ROBOTS = {"world", "robot1", "robot2"}


def test_every_package_under_fleet_is_installed():
    """pyproject.toml lists the packages (templates/ is mapped onto fleet.templates), so a new
    subpackage must be added there; and a folder of modules without __init__.py is no package."""
    setuptools = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    folders = {path.parent for path in (REPO / "fleet").rglob("*.py") if "__pycache__" not in path.parts}
    assert [str(f.relative_to(REPO)) for f in sorted(folders) if not (f / "__init__.py").exists()] == []
    found = {".".join(folder.relative_to(REPO).parts) for folder in folders}
    assert set(setuptools["packages"]) == found | {"fleet.templates"}
    assert setuptools["package-dir"] == {"fleet.templates": "templates"}


def _run(command: list, cwd: Path, env: dict[str, str], timeout: float) -> subprocess.CompletedProcess:
    done = subprocess.run([str(c) for c in command], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, f"{' '.join(map(str, command))}:\n{done.stdout}\n{done.stderr}"
    return done


def _clean_env(venv: Path) -> dict[str, str]:
    """This process's environment without anything that would let the installed fleet see this
    checkout, this test's virtual environment or its ROS settings (the process marker stays, so
    whatever the test leaves running is found and stopped)."""
    dropped = {"PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV", "AMENT_PREFIX_PATH"}
    kept = {MARKER_VARIABLE, "ROS_LOG_DIR"}
    env = {
        key: value
        for key, value in os.environ.items()
        if key in kept or (key not in dropped and not key.startswith(("FLEET_", "ROS_", "RMW_", "FASTDDS_")))
    }
    env["PATH"] = os.pathsep.join([str(venv / "bin"), env.get("PATH", "")])
    return env


@pytest.mark.integration
@pytest.mark.timeout(INSTALL_TIMEOUT + 300)
def test_installed_wheel_renders_and_deploys_outside_the_checkout(tmp_path, ros_domain):
    timings: dict[str, float] = {}
    started = time.monotonic()

    def lap(step: str) -> None:
        nonlocal started
        timings[step] = round(time.monotonic() - started, 1)
        started = time.monotonic()

    source = tmp_path / "source"
    source.mkdir()
    for name in SOURCES:
        if (REPO / name).is_dir():
            shutil.copytree(REPO / name, source / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy(REPO / name, source / name)
    venv = tmp_path / "venv"
    env = _clean_env(venv)
    _run([sys.executable, "-m", "venv", venv], tmp_path, env, 120)
    lap("venv")
    _run(
        [venv / "bin" / "pip", "wheel", "--quiet", "--no-deps", "--wheel-dir", tmp_path / "dist", source],
        tmp_path,
        env,
        300,
    )
    (wheel,) = (tmp_path / "dist").glob("fleet-*.whl")
    lap("wheel")
    _run([venv / "bin" / "pip", "install", "--quiet", wheel], tmp_path, env, INSTALL_TIMEOUT)
    lap("install")

    work = tmp_path / "work"
    work.mkdir()
    data = yaml.safe_load((REPO / "fleets" / "two_robots.yaml").read_text())
    data["ros"]["domain_id"] = ros_domain
    (work / "two_robots.yaml").write_text(yaml.safe_dump(data, sort_keys=False))

    where = _run([venv / "bin" / "python", "-c", "import fleet; print(fleet.__file__)"], work, env, 60)
    assert where.stdout.startswith(str(venv)), where.stdout
    _run([venv / "bin" / "fleet", "render", "two_robots.yaml", "-o", "out"], work, env, 120)
    for path in ("robot1/robot1.launch.yaml", "robot2/robot2.params.yaml", "world/world.launch.yaml"):
        assert (work / "out" / path).stat().st_size > 0, path
    lap("render")

    env.update(FLEET_STATE_DIR=str(tmp_path / "state"), FLEET_CONNECT=f"tcp/127.0.0.1:{free_tcp_port()}")
    fleet = venv / "bin" / "fleet"
    try:
        _run([fleet, "deploy", "two_robots.yaml", "--timeout", "90"], work, env, 150)
        lap("deploy")
        status = json.loads(_run([fleet, "status", "--json"], work, env, 60).stdout)
        robots = {row["name"]: row for row in status["robots"]}
        assert set(robots) == ROBOTS and {row["state"] for row in robots.values()} == {"running"}, robots
        # The nodes run from the new environment: its interpreter, its fleet_nodes scripts.
        for row in robots.values():
            for node in row["nodes"]:
                command = psutil.Process(node["pid"]).cmdline()
                assert any(part.startswith(str(venv)) for part in command), (row["name"], command)
    finally:
        down = subprocess.run([fleet, "down", "--all"], cwd=work, env=env, capture_output=True, text=True, timeout=90)
    assert down.returncode == 0, down.stdout + down.stderr
    lap("down")
    print(f"wheel install and use, seconds per step: {timings}")
