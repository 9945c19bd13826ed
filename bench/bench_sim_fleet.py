"""A simulated fleet on the default isolation, as a new user writes it: does it run, and at what cost?

For N robots (default 10 and 30) this writes a spec with one world and N diff-drive robots on
the agent `local`, each patrolling a small square on sim time, with nothing but the defaults
(`isolation: agent`, hosts of 25 robots, /clock at 100 Hz), brings it up with fleet.testing
(router, agent, world, hosts: real processes) and measures

- up: from the start of the deploy until `fleet deploy` says every robot runs (its data flows),
  or how many run when the deploy's timeout ends;
- CPU over 10 s once up, per kind of process (the hosts, the world's physics process, its ROS
  process, the agent), in % of one core, and the world's real-time factor.

`--isolation robot` (or `process`) runs the same fleet with that isolation instead: the CPU of
its node processes is then reported beside the hosts' (none).

Usage: .venv/bin/python bench/bench_sim_fleet.py [--robots 10 30] [--timeout 120]
       [--group-size G] [--isolation robot|process|agent] [--output bench/results/sim_fleet.md]
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
import time
from pathlib import Path

import psutil
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.bytecode import compile_checkout
from bench.machine import machine_description
from fleet.testing.control_plane import agent_key
from fleet.testing.fleet_handle import FleetHandle

TEMPLATES = Path(__file__).resolve().parent.parent / "templates"
WINDOW = 10.0  # s of CPU measurement once up
KINDS = {  # what a process is, by a piece of its command line (the first that matches)
    "hosts": "fleet.nodes.host",
    "world physics": "fleet_nodes/world",
    "node processes": "fleet_nodes/",  # isolation robot or process
    "world ROS": "fleet.world.ros_process",
    "agent": " agent ",
}


def spec(robots: int, group_size: int | None, isolation: str | None = None) -> dict:
    """N robots 2 m apart in rows of 10, each on a 1 m square, in a walled yard."""
    defaults: dict = {
        "template": "diff_drive",
        "model": {"type": "light", "radius": 0.2},
        "parameters": {"controller": {"waypoints": [1.0, 0.0, 1.0, 1.0, 0.0, 1.0, 0.0, 0.0]}},
    }
    if group_size is not None:
        defaults["group_size"] = group_size
    if isolation is not None:
        defaults["isolation"] = isolation
    return {
        "fleet": f"sim{robots}",
        "templates": str(TEMPLATES),
        "ros": {"use_sim_time": True},
        "world": {
            "obstacles": [
                {"name": "wall", "type": "wall", "position": [9.0, -2.0], "size": [24.0, 0.2, 0.5]},
            ]
        },
        "defaults": defaults,
        "robots": [
            {"name": f"bot{index:03d}", "pose": {"x": (index % 10) * 2.0, "y": (index // 10) * 3.0}}
            for index in range(robots)
        ],
    }


def cpu_by_kind(root: int) -> dict[str, float]:
    """% of one core used by each kind of process under `root` during WINDOW seconds."""
    processes = [root_process := psutil.Process(root), *root_process.children(recursive=True)]
    for process in processes:
        with contextlib.suppress(psutil.Error):
            process.cpu_percent()
    time.sleep(WINDOW)
    usage = dict.fromkeys(KINDS, 0.0)
    for process in processes:
        try:
            command = " ".join(process.cmdline())
            percent = process.cpu_percent()
        except psutil.Error:
            continue
        for kind, marker in KINDS.items():
            if marker in command:
                usage[kind] += percent
                break
    return usage


def measure(robots: int, timeout: float, group_size: int | None = None, isolation: str | None = None) -> dict:
    directory = Path(tempfile.mkdtemp(prefix=f"bench-sim-{robots}-"))
    path = directory / "fleet.yaml"
    path.write_text(yaml.safe_dump(spec(robots, group_size, isolation), sort_keys=False))
    handle = FleetHandle(path, directory / "run")
    result: dict = {"robots": robots}
    try:
        start = time.monotonic()
        try:
            handle.start(timeout)
            result["up"] = time.monotonic() - start
        except AssertionError:  # not every robot runs by the deploy's timeout
            result["up"] = None
        view = handle.status()
        result["running"] = sum(1 for row in view.robots if row.kind == "robot" and row.state == "running")
        agent_pid = handle.control.pid(agent_key(handle.agents()[0]))
        result["cpu"] = cpu_by_kind(agent_pid) if agent_pid else {}
        world = handle.world() or {}
        result["rtf"] = world.get("real_time_factor")
    finally:
        handle.close(check_leaks=False)
    return result


def report(results: list[dict], timeout: float, isolation: str | None) -> str:
    lines = [
        f"# A simulated fleet, isolation: {isolation or 'the default'}",
        "",
        f"Machine: {machine_description()}",
        "",
        "| robots | up (s) | running | " + " | ".join(f"CPU {kind}" for kind in KINDS) + " | RTF |",
        "|---|---|---|" + "---|" * len(KINDS) + "---|",
    ]
    for r in results:
        up = f"{r['up']:.1f}" if r["up"] is not None else f"not all in {timeout:.0f}"
        cpu = r["cpu"]
        rtf = f"{r['rtf']:.2f}" if isinstance(r["rtf"], int | float) else "-"
        lines.append(
            f"| {r['robots']} | {up} | {r['running']}/{r['robots']} | "
            + " | ".join(f"{cpu.get(kind, 0.0):.0f}%" for kind in KINDS)
            + f" | {rtf} |"
        )
    lines += [
        "",
        "Up: from the deploy's start until it reports every robot running (data flowing).",
        f"CPU: % of one core over {WINDOW:.0f} s once up (or at the timeout); hosts summed.",
    ]
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robots", type=int, nargs="+", default=[10, 30])
    parser.add_argument("--timeout", type=float, default=120.0)
    parser.add_argument("--group-size", type=int, default=None, help="robots per host (default: the spec's default)")
    parser.add_argument("--isolation", default=None, help="robot, process or agent (default: the spec's default)")
    parser.add_argument("--output", type=Path, default=Path(__file__).parent / "results" / "sim_fleet.md")
    args = parser.parse_args()
    compile_checkout()
    results = [measure(robots, args.timeout, args.group_size, args.isolation) for robots in args.robots]
    text = report(results, args.timeout, args.isolation)
    print(text)
    args.output.write_text(text)


if __name__ == "__main__":
    main()
