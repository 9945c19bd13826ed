"""Run every benchmark, one after the other; each writes its table to bench/results/<name>.md,
and then the figures (bench/plots.py: PNG of time and memory against robots) are drawn from them.

    .venv/bin/python bench/run_all.py            # everything (about 20 minutes on 2 cores)
    .venv/bin/python bench/run_all.py expand cli # some of them (and the figures)

Run them on an otherwise idle machine: they measure wall time on 2 cores.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parent
BENCHMARKS = {
    "cli": ["bench_cli.py"],
    "expand": ["bench_expand.py"],
    "render_scaling": ["bench_expand.py", "--scaling"],
    "world": ["bench_world.py"],
    "isolation": ["bench_isolation.py"],
    "sim_fleet": ["bench_sim_fleet.py"],
    "control": ["bench_control.py"],
    "dataplane": ["bench_dataplane.py"],
    "plots": ["plots.py"],  # last: draws what the others wrote
}


def main(names: list[str]) -> int:
    failed = []
    names = [*(names or BENCHMARKS), *([] if "plots" in names else ["plots"])]
    for name in dict.fromkeys(names):
        if name not in BENCHMARKS:
            print(f"unknown benchmark {name!r} (known: {', '.join(BENCHMARKS)})", file=sys.stderr)
            return 2
        print(f"=== {name}", flush=True)
        if subprocess.run([sys.executable, str(BENCH / BENCHMARKS[name][0]), *BENCHMARKS[name][1:]]).returncode:
            failed.append(name)
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
