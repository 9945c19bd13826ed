"""Real-time factor of the shared world against robot count, light model and husky.

Each configuration runs in its own process (fresh pybullet and rclpy): N robots on a 2 m grid inside
a walled arena with a few pillars, every robot driving a circle (so contacts happen), odometry at
50 Hz and 360-beam scans at 10 Hz published through rclpy, /clock at 100 Hz, status file at 4 Hz,
paced as fast as possible for a fixed sim duration.  RTF = sim seconds / wall seconds of the run
(start-up excluded, reported separately).

    .venv/bin/python bench/bench_world.py            # full table -> bench/results/world.md (+ .json)
    .venv/bin/python bench/bench_world.py --quick    # smaller counts, shorter runs, no file
    .venv/bin/python bench/bench_world.py --baseline DIR   # the same runs of the checkout in DIR and of
        # this one, in turn (A B A B ...), medians -> bench/results/world_compare.md

CPU counts the world process and its status writer (the child process that encodes the status file).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.bytecode import compile_checkout
from bench.machine import machine_info

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results" / "world.md"
COMPARE = ROOT / "bench" / "results" / "world_compare.md"
LIGHT_COUNTS = [1, 10, 50, 100, 200, 300, 500]
HUSKY_COUNTS = [1, 10, 30, 60, 100]
COMPARED = [("light", 100), ("light", 200), ("light", 500), ("husky", 30), ("husky", 60)]
MAX_PREDICTED_WALL = 120.0  # s: skip a husky count predicted to run longer than this


def world_yaml(model: str, count: int) -> dict:
    side = max(1, math.ceil(math.sqrt(count)))
    spacing = 2.5 if model == "husky" else 2.0
    half = side * spacing / 2 + 1.5
    robots = []
    for i in range(count):
        x = (i % side - (side - 1) / 2) * spacing
        y = (i // side - (side - 1) / 2) * spacing
        robots.append(
            {
                "name": f"robot{i + 1}",
                "model": {"type": model},
                "pose": {"x": x, "y": y, "yaw": 0.3 * i},
                "lidar": {"beams": 360, "rate": 10.0, "range_min": 0.12, "range_max": 8.0},
                "odom_rate": 50.0,
                "cmd_timeout": 0.5,
            }
        )
    obstacles: list[dict[str, Any]] = [
        {"name": "north", "type": "wall", "position": [0.0, half], "size": [2 * half, 0.2, 1.0]},
        {"name": "south", "type": "wall", "position": [0.0, -half], "size": [2 * half, 0.2, 1.0]},
        {"name": "east", "type": "wall", "position": [half, 0.0], "size": [0.2, 2 * half, 1.0]},
        {"name": "west", "type": "wall", "position": [-half, 0.0], "size": [0.2, 2 * half, 1.0]},
    ]
    # pillars in the middle of grid cells (between robots)
    for k in range(min(side - 1, 6)):
        px = (k - (side - 2) / 2) * spacing
        obstacles.append(
            {
                "name": f"pillar{k}",
                "type": "cylinder",
                "position": [px, spacing / 2 if side > 1 else 1.5],
                "radius": 0.2,
                "height": 1.0,
            }
        )
    return {
        "fleet": f"bench_{model}_{count}",
        "physics_rate": 240.0,
        "real_time": False,
        "clock_rate": 100.0,
        "obstacles": obstacles,
        "robots": robots,
    }


def run_one(model: str, count: int, sim_duration: float) -> dict:
    """Child process body: build the world, drive every robot, time app.run()."""
    import numpy as np

    from fleet.world.app import WorldApp
    from fleet.world.ros_process import RosProcess

    published = {"odom": 0, "scan": 0}
    odom, scan = RosProcess.publish_odom, RosProcess.publish_scans

    def count_odom(self, rows, *a):
        published["odom"] += len(rows)
        odom(self, rows, *a)

    def count_scan(self, rows, *a):
        published["scan"] += len(rows)
        scan(self, rows, *a)

    # Count what the world hands its ROS process by wrapping the class's methods (this child only).
    RosProcess.publish_odom, RosProcess.publish_scans = count_odom, count_scan  # type: ignore[method-assign]
    with tempfile.TemporaryDirectory() as tmp:
        config = Path(tmp) / "world.yaml"
        config.write_text(yaml.safe_dump(world_yaml(model, count)))
        t0 = time.perf_counter()
        bridge = RosProcess([])
        app = WorldApp(config, Path(tmp) / "status.json", as_fast_as_possible=True, bridge=bridge)
        app.step()  # gives the ROS process the robots
        setup = time.perf_counter() - t0
        spawned = len(app.robots)
        # commands that never time out: drive circles, half of them the other way
        bridge.hold(np.array([(0.5, 0.3 if i % 2 else -0.3) for i in range(spawned)]).reshape(-1, 2))
        app.run(sim_duration=0.5)  # warm-up
        published.update(odom=0, scan=0)
        contacts0 = app.contacts_count
        cpu0 = _cpu_seconds()
        t0 = time.perf_counter()
        app.run(sim_duration=sim_duration)
        wall = time.perf_counter() - t0
        cpu = _cpu_seconds() - cpu0
        contacts = app.contacts_count - contacts0
        rss = _rss_mib()
        app.close()
    return {
        "model": model,
        "robots": spawned,
        "sim": sim_duration,
        "wall": wall,
        "rtf": sim_duration / wall,
        "cpu_share": cpu / wall,
        "setup": setup,
        "odom_hz": published["odom"] / sim_duration / max(spawned, 1),
        "scan_hz": published["scan"] / sim_duration / max(spawned, 1),
        "contacts": contacts,
        "rss_mib": rss,
        "load": os.getloadavg()[0],
    }


def _rss_mib() -> float:
    """Resident memory of this process and of its children (ROS process, status writer), MiB."""
    import psutil

    total = 0
    for process in [psutil.Process(), *psutil.Process().children(recursive=True)]:
        with contextlib.suppress(psutil.Error):
            total += process.memory_info().rss
    return total / 2**20


def _cpu_seconds() -> float:
    """User + system seconds of this process and of its children (ROS process, status writer)."""
    import psutil

    total = 0.0
    for process in [psutil.Process(), *psutil.Process().children(recursive=True)]:
        with contextlib.suppress(psutil.Error):
            times = process.cpu_times()
            total += times.user + times.system
    return total


def child(model: str, count: int, sim: float, env: dict, script: Path = Path(__file__)) -> dict | None:
    done = subprocess.run(
        [sys.executable, str(script), "--child", model, str(count), str(sim)],
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    for line in done.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    sys.stderr.write(done.stdout[-2000:] + done.stderr[-2000:])
    return None


def table(rows: list[dict]) -> str:
    out = [
        "| model | robots | sim s | wall s | RTF | CPU (cores) | odom Hz/robot | scan Hz/robot | contacts | start-up s | RSS MiB | load |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        if r.get("skipped"):
            out.append(f"| {r['model']} | {r['robots']} | - | - | skipped: {r['skipped']} | | | | | | |")
            continue
        out.append(
            f"| {r['model']} | {r['robots']} | {r['sim']:.0f} | {r['wall']:.2f} | **{r['rtf']:.2f}** | "
            f"{r['cpu_share']:.2f} | {r['odom_hz']:.1f} | {r['scan_hz']:.1f} | {r['contacts']} | "
            f"{r['setup']:.2f} | {r['rss_mib']:.0f} | {r.get('load', float('nan')):.1f} |"
        )
    return "\n".join(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--baseline", type=Path, help="a checkout to compare with (its bench/bench_world.py)")
    parser.add_argument("--repeats", type=int, default=3, help="pairs per configuration with --baseline")
    parser.add_argument("--child", nargs=3, metavar=("MODEL", "COUNT", "SIM"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        model, count, sim = args.child
        print("RESULT " + json.dumps(run_one(model, int(count), float(sim))), flush=True)
        return
    compile_checkout()

    sys.path.insert(0, str(ROOT))
    from fleet.testing.isolation import reserve_domain_id, ros_environment

    if args.baseline:
        compile_checkout(args.baseline.resolve())
        compare(args.baseline.resolve(), args.repeats)
        return
    light_counts, husky_counts = ([1, 10, 50], [1, 10]) if args.quick else (LIGHT_COUNTS, HUSKY_COUNTS)
    light_sim, husky_sim = (3.0, 2.0) if args.quick else (10.0, 5.0)
    rows: list[dict] = []
    with reserve_domain_id() as domain:
        env = ros_environment(domain.domain_id)
        env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
        for count in light_counts:
            row = child("light", count, light_sim, env)
            if row:
                rows.append(row)
                print(table([row]).splitlines()[-1], flush=True)
        per_robot_step = None
        for count in husky_counts:
            if per_robot_step is not None:
                predicted = per_robot_step * count * husky_sim
                if predicted > MAX_PREDICTED_WALL:
                    rows.append(
                        {
                            "model": "husky",
                            "robots": count,
                            "skipped": f"predicted {predicted:.0f} s wall for {husky_sim:.0f} s sim",
                        }
                    )
                    print(f"husky {count}: skipped (predicted {predicted:.0f} s)", flush=True)
                    continue
            row = child("husky", count, husky_sim, env)
            if row:
                rows.append(row)
                per_robot_step = row["wall"] / husky_sim / row["robots"]
                print(table([row]).splitlines()[-1], flush=True)
    info = machine_info()
    text = table(rows)
    print(text)
    if args.quick:
        return
    RESULTS.write_text(
        "# World benchmark: real-time factor against robot count\n\n"
        f"Measured {time.strftime('%Y-%m-%d %H:%M')} with `bench/bench_world.py` on {info['nproc']} CPUs "
        f"({info['cpu']}), {info['ram']} RAM, Python {info['python']}, kernel {info['kernel']}; "
        f"load average at the end {info['load']} (the machine is shared with other work, so numbers "
        "vary by some percent between runs).\n\n"
        "Setup: one world (its physics process and its ROS process), robots on a grid in a walled arena with "
        "pillars, every robot driving a circle; physics 240 Hz (10 solver iterations); per robot odometry 50 Hz "
        "and a 360-beam lidar at 10 Hz (numpy ray casting) published through rclpy (FastDDS, no subscribers), "
        f"/clock 100 Hz, status file 4 Hz; as fast as possible for {light_sim:.0f} s (light) / {husky_sim:.0f} s "
        "(husky) of sim time after 0.5 s of warm-up. RTF = sim time / wall time. CPU = CPU time of the world's "
        "processes (physics, ROS, status writer) / wall time (1.0 = one core); RSS: theirs together.\n\n"
        + text
        + "\n\nTargets: RTF >= 1.0 with 500 light robots, >= 1.0 with 60 husky.\n\n"
        "Notes: the world's cost per published message (conversion, serialization, FastDDS write) is "
        "~10-25 us and is included; nobody subscribes, so delivery costs of real subscribers (in their own "
        "processes, on the same cores) are not. Husky counts are run up to the first predicted to take "
        f"more than {MAX_PREDICTED_WALL:.0f} s of wall time (none skipped when every row has numbers). "
        "Light-model cost grows faster than linearly with robot count because each scan sees more robots "
        "within range_max in a denser arena.\n"
    )
    RESULTS.with_suffix(".json").write_text(json.dumps({"machine": info, "rows": rows}, indent=1) + "\n")
    print(f"wrote {RESULTS}")


def compare(baseline: Path, repeats: int) -> None:
    """RTF of the baseline checkout and of this one, run in turn on the same machine."""
    from fleet.testing.isolation import reserve_domain_id, ros_environment

    sims = {"light": 5.0, "husky": 5.0}
    lines = [
        "| model | robots | RTF before (median) | RTF after (median) | after / before | CPU-s per sim-s before | after | load averages |",
        "|---|---:|---:|---:|---:|---:|---:|---|",
    ]
    data = []
    with reserve_domain_id() as domain:
        for model, count in COMPARED:
            runs: dict[str, list[dict]] = {"before": [], "after": []}
            for _ in range(repeats):
                for label, root in (("before", baseline), ("after", ROOT)):
                    env = ros_environment(domain.domain_id)
                    env["PYTHONPATH"] = str(root) + os.pathsep + env.get("PYTHONPATH", "")
                    row = child(model, count, sims[model], env, root / "bench" / "bench_world.py")
                    if row:
                        row.setdefault("load", os.getloadavg()[0])
                        runs[label].append(row)
                        print(f"{label} {model} {count}: RTF {row['rtf']:.2f} (load {row['load']:.1f})", flush=True)
            if not runs["before"] or not runs["after"]:
                continue
            before = statistics.median(r["rtf"] for r in runs["before"])
            after = statistics.median(r["rtf"] for r in runs["after"])
            cpu = {k: statistics.median(r["cpu_share"] * r["wall"] / r["sim"] for r in v) for k, v in runs.items()}
            loads = ", ".join(f"{r['load']:.1f}" for r in runs["before"] + runs["after"])
            lines.append(
                f"| {model} | {count} | {before:.2f} | **{after:.2f}** | {after / before:.1f}x | "
                f"{cpu['before']:.2f} | {cpu['after']:.2f} | {loads} |"
            )
            data.append({"model": model, "robots": count, "runs": runs})
    info = machine_info()
    COMPARE.write_text(
        "# World benchmark: before and after, run in turn\n\n"
        f"Measured {time.strftime('%Y-%m-%d %H:%M')} with `bench/bench_world.py --baseline` on {info['nproc']} CPUs "
        f"({info['cpu']}), {info['ram']} RAM, Python {info['python']}; load average at the end {info['load']}. "
        f"{repeats} runs each of the baseline checkout and this one, in turn (before, after, before, ...), "
        "as fast as possible for 5 s of sim time, the same world as world.md; medians. "
        "CPU-s per sim-s: CPU seconds of the world's processes per second of sim time (the work, "
        "whatever share of the cores it got); the load averages are those at the end of each run "
        "(before runs first, then after runs).\n\n" + "\n".join(lines) + "\n"
    )
    COMPARE.with_suffix(".json").write_text(json.dumps({"machine": info, "configs": data}, indent=1) + "\n")
    print("\n".join(lines))
    print(f"wrote {COMPARE}")


if __name__ == "__main__":
    main()
