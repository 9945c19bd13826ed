"""Benchmark: expanding and writing a 1,000-robot fleet spec, against writing the same bytes.

Run: .venv/bin/python bench/bench_expand.py [--robots 1000] [--repeat 7]
Prints medians and writes bench/results/expand.md with the machine description.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.machine import machine_description
from fleet.cli.render_cmd import write_bundles
from fleet.expand import expand_fleet
from fleet.spec import load_spec


def make_spec(robots: int, path: Path, agents: int = 10, simulated_every: int = 1) -> None:
    """A fleet of `robots` robots over `agents` agents, with a world of 20 obstacles hosting every
    `simulated_every`-th robot (the others are real robots): a third have their own parameters."""
    spec = {
        "fleet": "bench",
        "world": {
            "obstacles": [
                {"name": f"o{i}", "type": "box", "position": [i * 3.0, -5.0], "size": [1, 1, 1]} for i in range(20)
            ]
        },
        "agents": {f"host{i}": {} for i in range(agents)},
        "defaults": {"agent": "host0", "parameters": {"controller": {"max_speed": 0.6}}},
        "robots": [
            {
                "name": f"robot{i}",
                "agent": f"host{i % agents}",
                "pose": {"x": (i % 40) * 1.0, "y": (i // 40) * 1.0},
                **({} if i % simulated_every == 0 else {"simulated": False}),
                "parameters": {"controller": {"waypoints": [1.0, 0.0, 1.0, 1.0]}} if i % 3 == 0 else {},
            }
            for i in range(robots)
        ],
    }
    path.write_text(yaml.safe_dump(spec))


def time_render(spec_path: Path, out: Path) -> float:
    start = time.perf_counter()
    expansion = expand_fleet(load_spec(spec_path))
    write_bundles(expansion, out, "both")
    return time.perf_counter() - start


def time_expand_only(spec_path: Path) -> float:
    start = time.perf_counter()
    expand_fleet(load_spec(spec_path))
    return time.perf_counter() - start


def time_plain_write(files: dict[Path, str]) -> float:
    start = time.perf_counter()
    for path, text in files.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--robots", type=int, default=1000)
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as temporary:
        root = Path(temporary)
        spec_path = root / "fleet.yaml"
        make_spec(args.robots, spec_path)
        render_times, write_times, expand_times = [], [], []
        for run in range(args.repeat):
            expand_times.append(time_expand_only(spec_path))
            out = root / f"render{run}"
            render_times.append(time_render(spec_path, out))
            files = {root / f"plain{run}" / p.relative_to(out): p.read_text() for p in out.rglob("*") if p.is_file()}
            write_times.append(time_plain_write(files))
        size = sum(len(text.encode()) for text in files.values())
    render, write = statistics.median(render_times), statistics.median(write_times)
    expand = statistics.median(expand_times)
    lines = [
        f"# Expansion benchmark ({args.robots} robots)",
        "",
        f"Machine: {machine_description()}",
        "",
        "| what | median (s) | min (s) | max (s) |",
        "|---|---|---|---|",
        f"| validate + expand + write {len(files)} files ({size / 1e6:.1f} MB) | {render:.3f} | {min(render_times):.3f} | {max(render_times):.3f} |",
        f"| validate + expand only (no writing) | {expand:.3f} | {min(expand_times):.3f} | {max(expand_times):.3f} |",
        f"| write the same bytes to the same number of files | {write:.3f} | {min(write_times):.3f} | {max(write_times):.3f} |",
        "",
        f"Ratio render / plain write: {render / write:.1f}x (target: under 1 s wall, within 3x of plain writing).",
        f"Runs: {args.repeat}.",
    ]
    report = "\n".join(lines) + "\n"
    print(report)
    (Path(__file__).parent / "results" / "expand.md").write_text(report)


if __name__ == "__main__":
    main()
