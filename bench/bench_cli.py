"""Benchmark: start-up of the `fleet` command (`fleet --help`, `fleet render --help`).

Run: .venv/bin/python bench/bench_cli.py [--runs 15].  Target: `fleet --help` under 0.3 s.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.bytecode import compile_checkout
from bench.machine import machine_description
from bench.user_shell import user_env

FLEET = Path(sys.executable).parent / "fleet"
REPO = Path(__file__).resolve().parent.parent


def timed(command: list[str], runs: int) -> list[float]:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        subprocess.run(
            command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True, cwd=REPO, env=user_env()
        )
        times.append(time.perf_counter() - start)
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--runs", type=int, default=15)
    args = parser.parse_args()
    compile_checkout()
    cases = {
        "python -c pass (interpreter + ROS wheels' re-exec)": [sys.executable, "-c", "pass"],
        "fleet --help": [str(FLEET), "--help"],
        "fleet render --help": [str(FLEET), "render", "--help"],
        "fleet render fleets/two_robots.yaml --json": [str(FLEET), "render", "fleets/two_robots.yaml", "--json"],
    }
    lines = [
        "# CLI start-up benchmark",
        "",
        f"Machine: {machine_description()}",
        "",
        "| command | median (s) | min (s) | max (s) |",
        "|---|---|---|---|",
    ]
    for label, command in cases.items():
        times = timed(command, args.runs)
        lines.append(f"| `{label}` | {statistics.median(times):.3f} | {min(times):.3f} | {max(times):.3f} |")
    lines += ["", f"Runs: {args.runs} each. Target: `fleet --help` under 0.3 s."]
    report = "\n".join(lines) + "\n"
    print(report)
    (Path(__file__).parent / "results" / "cli.md").write_text(report)


if __name__ == "__main__":
    main()
