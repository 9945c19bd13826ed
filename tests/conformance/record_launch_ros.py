"""Record what real launch_ros starts for each corpus file, as expected data (expected/*.json).

Run by hand, where `launch` and `launch_ros` (Jazzy) are importable, from the checkout's root:

    python -m tests.conformance.record_launch_ros [corpus/NAME ...]

Each file runs in a process of its own (launch numbers processes with one counter per Python
process) in a throw-away ament prefix whose executables are the recorder (probe.py).  A file that
launch refuses or fails on is recorded as {"fails": true}.  CI does not run this: it compares the
embedded runner with what this wrote (test_conformance.py).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from tests.conformance.prefix import (
    CORPUS,
    EXPECTED,
    PACKAGE,
    base_env,
    corpus_files,
    launch_args,
    make_prefix,
    normalise,
)

QUIET = 1.5  # seconds without a new record: everything has started (the corpus' timers are shorter)
NOTHING_AFTER = 10.0  # seconds after which a file that started nothing is taken to start nothing
AT_LEAST = 3.0  # seconds before that counts: a busy machine starts the first process late


def wait_quiet(records: Path, names: dict[int, str], done: threading.Event) -> None:
    """Until every process launch started has written its record, and nothing new came for a while."""
    count, began = -1, time.monotonic()
    since = began
    while not done.is_set():
        now = len(list(records.glob("*.json")))
        if now != count:
            count, since = now, time.monotonic()
        quiet = time.monotonic() - since > QUIET and time.monotonic() - began > AT_LEAST
        if quiet and now >= len(names) and (names or time.monotonic() - began > NOTHING_AFTER):
            return
        time.sleep(0.05)


def record_one(name: str, out: Path) -> None:
    """In this process: run corpus file `name` under launch, write its normalised record."""
    # launch and launch_ros are not the project's dependencies: importable only where recording.
    from launch.actions import IncludeLaunchDescription, RegisterEventHandler  # type: ignore[import-not-found]
    from launch.event_handlers import OnProcessStart  # type: ignore[import-not-found]
    from launch.launch_description_sources import AnyLaunchDescriptionSource  # type: ignore[import-not-found]

    from launch import LaunchDescription, LaunchService  # type: ignore[attr-defined]

    with tempfile.TemporaryDirectory() as scratch:
        prefix = make_prefix(Path(scratch) / "prefix")
        records = Path(scratch) / "records"
        records.mkdir()
        env = base_env(prefix, records)
        os.environ.clear()
        os.environ.update(env)
        os.chdir(scratch)
        path = prefix / "share" / PACKAGE / "launch" / name
        names: dict[int, str] = {}
        handler = OnProcessStart(on_start=lambda event, context: names.__setitem__(event.pid, event.process_name))
        service = LaunchService(argv=launch_args(path))
        service.include_launch_description(
            LaunchDescription(
                [
                    RegisterEventHandler(handler),
                    IncludeLaunchDescription(AnyLaunchDescriptionSource(str(path)), launch_arguments=_arguments(path)),
                ]
            )
        )
        done = threading.Event()

        def stop() -> None:
            wait_quiet(records, names, done)
            service.shutdown()

        threading.Thread(target=stop, daemon=True).start()
        code = service.run()
        done.set()
        result: dict = {"fails": True} if code != 0 else {"processes": normalise(records, names, prefix, env)}
    out.write_text(json.dumps(result, indent=1, ensure_ascii=False, sort_keys=True) + "\n")


def _arguments(path: Path) -> list[tuple[str, str]]:
    return [tuple(item.split(":=", 1)) for item in launch_args(path)]  # type: ignore[misc]


def main(argv: list[str]) -> int:
    if argv[:1] == ["--one"]:
        record_one(argv[1], Path(argv[2]))
        return 0
    files = [CORPUS / Path(item).name for item in argv] or corpus_files()
    EXPECTED.mkdir(exist_ok=True)
    for file in files:
        out = EXPECTED / (file.name + ".json")
        run = subprocess.run(
            [sys.executable, "-m", "tests.conformance.record_launch_ros", "--one", file.name, str(out)],
            capture_output=True,
            text=True,
            timeout=60,
        )
        if run.returncode != 0:
            sys.stderr.write(f"{file.name}: recording failed:\n{run.stderr[-2000:]}\n")
            continue
        print(f"{file.name}: {out.read_text()[:60].strip()!r}...")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
