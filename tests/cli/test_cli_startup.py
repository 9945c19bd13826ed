"""`fleet --help` stays fast: no heavy module is imported until a command needs it."""

from __future__ import annotations

import json
import subprocess
import sys

HEAVY = ["rclpy", "zenoh", "pybullet", "numpy", "matplotlib", "pydantic", "yaml", "jinja2", "psutil"]

PROBE = """
import json, sys
from fleet.cli import app
from typer.main import get_command
get_command(app)  # build the whole command tree, as --help does
print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in {heavy})))
"""


def test_help_imports_no_heavy_module():
    result = subprocess.run(
        [sys.executable, "-c", PROBE.format(heavy=set(HEAVY))], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout) == []


def test_help_lists_the_commands():
    result = subprocess.run([sys.executable, "-m", "fleet", "--help"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0
    for command in ("render", "run", "deploy", "status", "world"):
        assert command in result.stdout


def test_version_is_the_installed_one():
    from importlib.metadata import version

    result = subprocess.run([sys.executable, "-m", "fleet", "--version"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert result.stdout == f"fleet {version('fleet')}\n"


# What `fleet status` imports to ask, build and print the view: the protocol's pydantic and
# zenoh, nothing of what expansion, the runtime or the world need.
STATUS_PROBE = """
import json, sys
import fleet.cli.output, fleet.cli.status_view, fleet.client, fleet.plan
print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in {heavy})))
"""


def test_status_imports_only_what_it_uses():
    heavy = {"rclpy", "pybullet", "numpy", "matplotlib", "yaml", "jinja2", "psutil"}
    result = subprocess.run(
        [sys.executable, "-c", STATUS_PROBE.format(heavy=heavy)], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout) == []


# The program's way out: its exit code, its objects frozen so that the interpreter's exit skips
# its garbage collection passes (fleet.cli.entry_point).
EXIT_PROBE = """
import atexit, gc, sys
atexit.register(lambda: print("frozen", gc.get_freeze_count() > 0, file=sys.stderr))
sys.argv = ["fleet", *{args}]
from fleet.cli import entry_point
entry_point()
"""


def test_the_program_exits_with_its_code_and_its_objects_frozen(tmp_path):
    missing = tmp_path / "missing.yaml"
    for args, code in ((["--version"], 0), (["render", str(missing)], 2)):
        result = subprocess.run(
            [sys.executable, "-c", EXIT_PROBE.format(args=args)], capture_output=True, text=True, timeout=60
        )
        assert result.returncode == code, result.stderr
        assert "frozen True" in result.stderr
