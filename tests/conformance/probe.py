"""The recorder: a tiny executable that writes what it was started with (its argv, the contents
of every --params-file it was given, its environment) to a JSON file in $FLEET_PROBE_DIR, then
waits to be stopped.  Installed as several executables of the package `fleet_probe` in a
throw-away ament prefix (prefix.py), it is started alike by real launch_ros (record_launch_ros.py)
and by the embedded runner (test_conformance.py): what each wrote is what they started.

Standard library only: it runs under whatever interpreter wrote the prefix."""

import json
import os
import signal
import sys
import time


def main() -> None:
    argv = sys.argv
    params = {}
    for index, argument in enumerate(argv[:-1]):
        if argument == "--params-file":
            path = argv[index + 1]
            with open(path, encoding="utf-8") as stream:
                params[path] = stream.read()
    record = {"pid": os.getpid(), "argv": argv, "params": params, "env": dict(os.environ), "cwd": os.getcwd()}
    directory = os.environ["FLEET_PROBE_DIR"]
    temporary = os.path.join(directory, f".{os.getpid()}.partial")
    with open(temporary, "w", encoding="utf-8") as stream:
        json.dump(record, stream)
    os.replace(temporary, os.path.join(directory, f"{os.getpid()}-{time.monotonic_ns()}.json"))
    signal.signal(signal.SIGINT, lambda *_: sys.exit(0))
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    while True:
        time.sleep(60)


if __name__ == "__main__":
    main()
