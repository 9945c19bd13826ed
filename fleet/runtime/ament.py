"""The ament index entries of the `fleet_nodes` package, and executable lookup like launch_ros.

`ros2 launch` (and our embedded runner) find `pkg`/`exec` through the ament index: the first
prefix of AMENT_PREFIX_PATH holding `share/ament_index/resource_index/packages/<pkg>`, then the
executable `<prefix>/lib/<pkg>/<exe>`.  The ros-jazzy-* wheels install their index into the
Python environment's prefix, so we do the same for `fleet_nodes`: a marker file, a package.xml
and one small Python script per executable that imports `fleet.nodes.<exe>` and runs `main()`.
"""

from __future__ import annotations

import os
import re
import sys
from collections.abc import Mapping
from pathlib import Path

from fleet.errors import LaunchFileError, did_you_mean
from fleet.files import write_atomic

PACKAGE = "fleet_nodes"
EXECUTABLES = ("controller", "battery", "safety", "world", "composite")
INDEX_DIR = Path("share") / "ament_index" / "resource_index" / "packages"

# What the nodes import at run time (exec_depend); the wheels of these provide the messages.
_EXEC_DEPENDS = (
    "rclpy",
    "rcl_interfaces",
    "std_msgs",
    "geometry_msgs",
    "nav_msgs",
    "sensor_msgs",
    "rosgraph_msgs",
    "diagnostic_msgs",
)


def default_prefix() -> Path:
    return Path(sys.prefix)


def _interpreter(prefix: Path) -> str:
    # The environment's own interpreter, so the scripts see the same site-packages (and the
    # ros wheels' bootstrap) whichever Python started the runner.
    candidate = prefix / "bin" / "python3"
    return str(candidate) if candidate.exists() else sys.executable


def _package_xml() -> str:
    depends = "\n".join(f"  <exec_depend>{name}</exec_depend>" for name in _EXEC_DEPENDS)
    return (
        '<?xml version="1.0"?>\n'
        '<package format="3">\n'
        f"  <name>{PACKAGE}</name>\n"
        "  <version>0.1.0</version>\n"
        "  <description>fleet robot nodes: controller, battery, safety, world, composite"
        "</description>\n"
        '  <maintainer email="fleet@example.invalid">fleet</maintainer>\n'
        "  <license>Apache-2.0</license>\n"
        f"{depends}\n"
        "  <export>\n"
        "    <build_type>ament_python</build_type>\n"
        "  </export>\n"
        "</package>\n"
    )


def _script(interpreter: str, executable: str) -> str:
    return (
        f"#!{interpreter}\n"
        f"# fleet_nodes/{executable}, written by fleet.runtime.ament.ensure_ament_prefix().\n"
        "import sys\n"
        f"from fleet.nodes.{executable} import main\n"
        "sys.exit(main())\n"
    )


def _write_if_changed(path: Path, content: str, mode: int) -> None:
    """Write atomically (temp file + rename), and only when the content differs."""
    try:
        if path.read_text() == content and (path.stat().st_mode & 0o777) == mode:
            return
    except OSError:
        pass
    write_atomic(path, content, mode=mode)


def ensure_ament_prefix(prefix: Path | None = None) -> Path:
    """Make `prefix` (default: this Python environment) an ament prefix holding fleet_nodes."""
    prefix = Path(prefix) if prefix is not None else default_prefix()
    _write_if_changed(prefix / INDEX_DIR / PACKAGE, "", 0o644)
    _write_if_changed(prefix / "share" / PACKAGE / "package.xml", _package_xml(), 0o644)
    interpreter = _interpreter(prefix)
    for executable in EXECUTABLES:
        _write_if_changed(prefix / "lib" / PACKAGE / executable, _script(interpreter, executable), 0o755)
    return prefix


def ament_prefix_path(env: Mapping[str, str] | None = None, prefix: Path | None = None) -> str:
    """AMENT_PREFIX_PATH of `env` (default os.environ) with our prefix appended if absent."""
    env = os.environ if env is None else env
    ours = str(Path(prefix) if prefix is not None else default_prefix())
    entries = [entry for entry in env.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if entry]
    if ours not in entries:
        entries.append(ours)
    return os.pathsep.join(entries)


def _prefixes(search_path: str) -> list[str]:
    return [entry for entry in search_path.split(os.pathsep) if entry]


def find_package_prefix(package: str, search_path: str) -> Path:
    """The first prefix of `search_path` (an AMENT_PREFIX_PATH value) that indexes `package`."""
    prefixes = _prefixes(search_path)
    for entry in prefixes:
        if (Path(entry) / INDEX_DIR / package).is_file():
            return Path(entry)
    searched = ", ".join(prefixes) or "(AMENT_PREFIX_PATH is empty)"
    indexed = {path.name for entry in prefixes for path in _listing(Path(entry) / INDEX_DIR)}
    raise LaunchFileError(
        f"package '{package}' not found in the ament index{did_you_mean(package, indexed)} (searched: {searched})"
    )


def _listing(directory: Path) -> list[Path]:
    try:
        return list(directory.iterdir())
    except OSError:
        return []


_NOT_FOUND = re.compile(r"package '([^']+)' not found in the ament index")


def missing_package(problem: str) -> str | None:
    """The package a problem reported by find_package_prefix (on an agent, say) names, if any."""
    found = _NOT_FOUND.search(problem)
    return found.group(1) if found else None


def indexes(package: str, search_path: str) -> Path | None:
    """The prefix of `search_path` indexing `package`, None when none does."""
    try:
        return find_package_prefix(package, search_path)
    except LaunchFileError:
        return None


def find_package_share(package: str, search_path: str) -> Path:
    """`$(find-pkg-share PKG)`: `<prefix>/share/<pkg>` of the prefix indexing the package."""
    return find_package_prefix(package, search_path) / "share" / package


def find_executable(package: str, executable: str, search_path: str) -> Path:
    """`<prefix>/lib/<pkg>/<exe>` of the first prefix indexing `package`, as launch_ros does."""
    prefix = find_package_prefix(package, search_path)
    candidate = prefix / "lib" / package / executable
    if candidate.is_file() and os.access(candidate, os.X_OK):
        return candidate
    # Say what the package has: a typo is the usual cause, and the paths are long (an error
    # line keeps 300 characters, cutting the middle of what is longer).
    has = {path.name for path in _listing(candidate.parent) if path.is_file() and os.access(path, os.X_OK)}
    listed = ", ".join(sorted(has)) or "no executable"
    raise LaunchFileError(
        f"executable '{executable}' of package '{package}' not found{did_you_mean(executable, has)}: "
        f"{candidate.parent} holds {listed}"
    )
