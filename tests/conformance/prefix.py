"""A throw-away ament prefix holding the recorder (probe.py) as the executables of package
`fleet_probe`, and the corpus under its share directory (so `$(find-pkg-share fleet_probe)` finds
the included files and parameter files), plus the normalisation of what the recorder wrote."""

from __future__ import annotations

import json
import os
import re
import shutil
import sys
from pathlib import Path
from typing import Any

import yaml

HERE = Path(__file__).parent
CORPUS = HERE / "corpus"
EXPECTED = HERE / "expected"
PACKAGE = "fleet_probe"
EXECUTABLES = ("probe", "talker", "listener", "my-tool")
INDEX = Path("share") / "ament_index" / "resource_index" / "packages"
# What each runner sets in every child for its own reasons (the embedded runner its log
# directory, unbuffered Python output and its own prefix; launch nothing): not the launch
# file's doing, so not compared.
RUNNER_VARIABLES = {"AMENT_PREFIX_PATH", "PYTHONUNBUFFERED", "ROS_LOG_DIR", "FLEET_PROBE_DIR", "OLDPWD", "PWD", "_"}


def corpus_files() -> list[Path]:
    """The corpus files run at the top (included-only files are named *.part.launch.*)."""
    return sorted(path for path in CORPUS.iterdir() if ".launch." in path.name and ".part." not in path.name)


def make_prefix(root: Path) -> Path:
    """The prefix under `root`; returns it."""
    (root / INDEX).mkdir(parents=True, exist_ok=True)
    (root / INDEX / PACKAGE).touch()
    lib = root / "lib" / PACKAGE
    lib.mkdir(parents=True, exist_ok=True)
    source = (HERE / "probe.py").read_text()
    for name in EXECUTABLES:
        path = lib / name
        path.write_text(f"#!{sys.executable}\n" + source)
        path.chmod(0o755)
    share = root / "share" / PACKAGE
    if share.exists():
        shutil.rmtree(share)
    shutil.copytree(CORPUS, share / "launch")
    return root


def base_env(prefix: Path, records: Path) -> dict[str, str]:
    """The environment both runners are given: this one, with the prefix and the record dir."""
    env = {key: value for key, value in os.environ.items() if not key.startswith(("FLEET_CONF_", "ROS_NAMESPACE"))}
    # Prefixes already set stay behind ours (where launch itself finds its grammar file).
    env["AMENT_PREFIX_PATH"] = os.pathsep.join(filter(None, [str(prefix), os.environ.get("AMENT_PREFIX_PATH")]))
    env["FLEET_PROBE_DIR"] = str(records)
    env["PYTHONUNBUFFERED"] = "1"
    env["FLEET_CONF_PRESET"] = "from-the-environment"  # the corpus reads it with $(env ...)
    env["FLEET_CONF_UNSET_ME"] = "present"  # the corpus unsets it
    return env


def normalise(records: Path, names: dict[int, str], prefix: Path, env: dict[str, str]) -> list[dict[str, Any]]:
    """What the recorder wrote, comparable between runs: paths under the prefix as $PREFIX,
    parameter files by their parsed contents in order, the environment as what was added,
    changed or removed relative to `env`; ordered like launch numbers its processes."""
    result: list[dict[str, Any]] = []
    for file in records.glob("*.json"):
        record = json.loads(file.read_text())
        if record["pid"] not in names:
            continue  # e.g. a respawned copy that started while stopping
        argv = list(record["argv"])
        params = []
        for index, argument in enumerate(argv[:-1]):
            if argument == "--params-file":
                path = argv[index + 1]
                params.append(yaml.safe_load(_swap(record["params"][path], prefix)))
                if not path.startswith(str(prefix)):
                    argv[index + 1] = "<launch_params temporary file>"
        seen = record["env"]
        added = {
            key: _swap(value, prefix)
            for key, value in sorted(seen.items())
            if key not in RUNNER_VARIABLES and env.get(key) != value
        }
        removed = sorted(key for key in env if key not in seen and key not in RUNNER_VARIABLES)
        entry: dict[str, Any] = {
            "process": names[record["pid"]],
            "argv": [_swap(argument, prefix) for argument in argv],
            "params": params,
            "env_added": added,
            "env_removed": removed,
        }
        if record["cwd"].startswith(str(prefix)):  # a working directory the launch file chose
            entry["cwd"] = _swap(record["cwd"], prefix)
        result.append(entry)
    result.sort(key=lambda entry: _number(entry["process"]))
    # Keep only the first of a process name (respawns while stopping)
    unique: dict[str, dict[str, Any]] = {}
    for entry in result:
        unique.setdefault(entry["process"], entry)
    return list(unique.values())


def _number(process: str) -> int:
    match = re.search(r"-(\d+)$", process)
    return int(match.group(1)) if match else 0


def _swap(text: str, prefix: Path) -> str:
    return text.replace(str(prefix), "$PREFIX")


def expected(path: Path) -> dict[str, Any]:
    return json.loads((EXPECTED / (path.name + ".json")).read_text())


def launch_args(path: Path) -> list[str]:
    """The launch arguments a corpus file is run with, written on its first line after `args:`."""
    first = path.read_text(encoding="utf-8").splitlines()[0]
    if "args:" not in first:
        return []
    text = first.split("args:", 1)[1].strip()
    return text.removesuffix("-->").split()
