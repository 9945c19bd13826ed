"""Benchmark: expanding and writing a 1,000-robot fleet spec, against writing the same bytes;
and with --scaling, `fleet render --json` of 10,000 and 20,000 robots (the cost must grow
linearly: 20,000 robots at most 2.2x the time of 10,000, and 10,000 under 3 s).

Run: .venv/bin/python bench/bench_expand.py [--robots 1000] [--repeat 7]
     .venv/bin/python bench/bench_expand.py --scaling [--sizes 10000 20000] [--repeat 5]
Prints medians and writes bench/results/expand.md (or expand_scaling.md) with the machine.
"""

from __future__ import annotations

import argparse
import gc
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.bytecode import compile_checkout
from bench.machine import machine_description
from bench.user_shell import user_env
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
        # Each agent takes its share (more than the default max_robots when 1,000 robots share one).
        "agents": {f"host{i}": {"max_robots": max(1, -(-robots // agents))} for i in range(agents)},
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


ROBOTS_PER_AGENT = 1000  # an agent takes at most 1024 units (fleet.wire.limits.MAX_BUNDLES)
SIMULATED_EVERY = 10  # a world.yaml of 1,000 simulated robots is 0.3 MB; an agent takes files up to 1 MiB


def scaling_spec(robots: int, path: Path) -> None:
    """A fleet that deploys: 1,000 robots per agent, and one robot in ten simulated in the world."""
    make_spec(robots, path, agents=max(1, robots // ROBOTS_PER_AGENT), simulated_every=SIMULATED_EVERY)


def time_cli_render(spec_path: Path) -> tuple[float, float]:
    """Wall and CPU seconds of `fleet render SPEC --json`, start-up included, as a user runs it."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(
        [str(Path(sys.executable).parent / "fleet"), "render", str(spec_path), "--json"],
        stdout=subprocess.DEVNULL,
        check=True,
        env=user_env(),
    )
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def time_stages(spec_path: Path) -> dict[str, float]:
    """CPU seconds of each stage of `render --json`, in this process."""
    from fleet.cli.output import json_text
    from fleet.cli.plan_view import plan_data

    gc.disable()  # as the command does (fleet.cli.render_cmd.paused_gc)
    try:
        clock = time.process_time
        start = clock()
        spec = load_spec(spec_path)
        loaded = clock()
        expansion = expand_fleet(spec)
        expanded = clock()
        data = plan_data(expansion)
        planned = clock()
        json_text(data)
        dumped = clock()
    finally:
        gc.enable()
    return {
        "load + validate": loaded - start,
        "expand": expanded - loaded,
        "plan table": planned - expanded,
        "JSON": dumped - planned,
    }


def scaling(sizes: list[int], repeat: int) -> None:
    with tempfile.TemporaryDirectory() as temporary:
        walls: dict[int, list[float]] = {}
        cpus: dict[int, list[float]] = {}
        stages: dict[int, dict[str, float]] = {}
        specs = {}
        for robots in sizes:
            specs[robots] = Path(temporary) / f"fleet{robots}.yaml"
            scaling_spec(robots, specs[robots])
        for _ in range(repeat):  # interleaved, so a busy moment touches every size alike
            for robots in sizes:
                wall, cpu = time_cli_render(specs[robots])
                walls.setdefault(robots, []).append(wall)
                cpus.setdefault(robots, []).append(cpu)
        for robots in sizes:
            stages[robots] = time_stages(specs[robots])
        size = {robots: specs[robots].stat().st_size for robots in sizes}
    median_wall = {robots: statistics.median(times) for robots, times in walls.items()}
    median_cpu = {robots: statistics.median(times) for robots, times in cpus.items()}
    lines = [
        "# Render scaling benchmark (`fleet render SPEC --json`)",
        "",
        f"Machine: {machine_description()}",
        "",
        f"Specs: {ROBOTS_PER_AGENT} robots per agent, one robot in {SIMULATED_EVERY} simulated in a world of 20 "
        "obstacles, a third of the robots with their own parameters (bench/bench_expand.py, make_spec).",
        "",
        "| robots | spec | wall median (s) | wall min (s) | wall max (s) | CPU median (s) |",
        "|---:|---:|---:|---:|---:|---:|",
    ]
    for robots in sizes:
        lines.append(
            f"| {robots} | {size[robots] / 1e6:.1f} MB | {median_wall[robots]:.2f} | {min(walls[robots]):.2f} | "
            f"{max(walls[robots]):.2f} | {median_cpu[robots]:.2f} |"
        )
    lines += ["", "CPU seconds of each stage, in one process (start-up and imports not included):", ""]
    names = list(next(iter(stages.values())))
    lines += ["| robots | " + " | ".join(names) + " |", "|---:|" + "---:|" * len(names)]
    for robots in sizes:
        lines.append(f"| {robots} | " + " | ".join(f"{stages[robots][name]:.2f}" for name in names) + " |")
    if len(sizes) >= 2:
        small, large = sizes[0], sizes[-1]
        lines += [
            "",
            f"Ratio {large} / {small} robots: wall {median_wall[large] / median_wall[small]:.2f}x, "
            f"CPU {median_cpu[large] / median_cpu[small]:.2f}x "
            f"(target: at most {2.2 * large / small / 2:.1f}x for {large / small:g}x the robots).",
        ]
    lines += [f"Target: {small} robots under 3 s. Runs: {repeat} of each size, interleaved."]
    report = "\n".join(lines) + "\n"
    print(report)
    (Path(__file__).parent / "results" / "expand_scaling.md").write_text(report)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--robots", type=int, default=1000)
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--scaling", action="store_true", help="time `fleet render --json` of big fleets")
    parser.add_argument("--sizes", type=int, nargs="+", default=[10000, 20000])
    args = parser.parse_args()
    compile_checkout()
    if args.scaling:
        scaling(args.sizes, args.repeat if args.repeat != 7 else 5)
        return
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
