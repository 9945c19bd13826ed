"""Memory and start-up time per robot: `isolation: process` vs `robot` vs `agent`.

For N robots (default 1, 10, 30) this writes one launch file per robot (controller, battery and
safety of fleet_nodes in /robotK, parameters from a file, as `fleet render` produces them),
starts one LaunchSession per robot in an isolated ROS domain (with `agent`, the sessions leave
their fleet nodes to one HostPool, as an agent does: host processes of --group-size robots),
and measures

- start-up: from the first start() until every node is in the ROS graph (seen by a probe node);
- memory: after the graph is complete and a settling pause, the sum over every node process of
  PSS (proportional set size: shared pages divided among the processes sharing them, so the sum
  is what the fleet really costs) and, for comparison, of RSS (counts shared pages once per
  process, so it overstates a sum).

Usage: .venv/bin/python bench/bench_isolation.py [--robots 10 30 100] [--isolation process robot agent]
       [--group-size 25] [--output bench/results/isolation.md]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import psutil

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.bytecode import compile_checkout
from bench.machine import machine_info
from fleet.runtime.hosting import HostPool
from fleet.runtime.processes import group_members
from fleet.runtime.supervisor import LaunchSession
from fleet.testing.hosting import start_hosted_robot
from fleet.testing.isolation import reserve_domain_id, ros_environment

LAUNCH = """\
launch:
- group:
  - push_ros_namespace: {{namespace: {robot}}}
  - node:
      pkg: fleet_nodes
      exec: controller
      name: controller
      param:
      - {{from: $(dirname)/{robot}.params.yaml}}
      - {{name: use_sim_time, value: 'false'}}
      remap:
      - {{from: cmd_vel, to: cmd_vel_nav}}
  - node:
      pkg: fleet_nodes
      exec: battery
      name: battery
      param:
      - {{from: $(dirname)/{robot}.params.yaml}}
  - node:
      pkg: fleet_nodes
      exec: safety
      name: safety
      param:
      - {{from: $(dirname)/{robot}.params.yaml}}
      remap:
      - {{from: cmd_vel_in, to: cmd_vel_nav}}
      - {{from: cmd_vel_out, to: cmd_vel}}
"""
PARAMS = """\
/{robot}/controller:
  ros__parameters: {{max_speed: 0.5}}
/{robot}/battery:
  ros__parameters: {{capacity: 100.0}}
/{robot}/safety:
  ros__parameters: {{safety_distance: 0.4}}
"""
NODES_PER_ROBOT = ("controller", "battery", "safety")
SETTLE = 3.0  # s after the graph is complete, before measuring memory
MIB = 1024 * 1024


def pss_and_rss(pid: int) -> tuple[int, int]:
    """Bytes of PSS and RSS of one process."""
    memory = psutil.Process(pid).memory_full_info()
    return memory.pss, memory.rss


class Probe:
    def __init__(self):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        self.context = Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("bench_probe", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def wait_for(self, expected: set, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if expected <= set(self.node.get_node_names_and_namespaces()):
                return True
            self.executor.spin_once(timeout_sec=0.05)
        return False

    def wait_gone(self, namespaces: set[str], timeout: float) -> None:
        """Let the previous case's nodes leave the graph before the next case starts."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            graph = self.node.get_node_names_and_namespaces()
            if not any(namespace in namespaces for _, namespace in graph):
                return
            self.executor.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()


def write_robots(robots: int, workdir: Path) -> tuple[list[Path], set]:
    robot_names = [f"robot{index + 1}" for index in range(robots)]
    paths = []
    for robot in robot_names:
        (workdir / f"{robot}.params.yaml").write_text(PARAMS.format(robot=robot))
        path = workdir / f"{robot}.launch.yaml"
        path.write_text(LAUNCH.format(robot=robot))
        paths.append(path)
    expected = {(node, f"/{robot}") for robot in robot_names for node in NODES_PER_ROBOT}
    return paths, expected


def cpu_seconds(pids: set[int]) -> float:
    total = 0.0
    for pid in pids:
        try:
            times = psutil.Process(pid).cpu_times()
            total += times.user + times.system
        except psutil.NoSuchProcess:
            pass
    return total


def run_case(robots: int, isolation: str, workdir: Path, env: dict, probe: Probe, group_size: int = 25) -> dict:
    paths, expected = write_robots(robots, workdir)
    pool = HostPool(workdir / "hosts", env, group_size) if isolation == "agent" else None
    sessions: list[LaunchSession] = []
    try:
        began = time.monotonic()
        for path in paths:
            log_dir = workdir / "logs" / path.stem
            if pool is not None:
                sessions.append(start_hosted_robot(path, pool, env, log_dir))
            else:
                sessions.append(LaunchSession(path, env=env, log_dir=log_dir, isolation=isolation, backend="embedded"))
                sessions[-1].start()
        complete = probe.wait_for(expected, timeout=120 + 5 * robots)
        startup = time.monotonic() - began
        if not complete:
            raise RuntimeError(f"{isolation}, {robots} robots: graph incomplete after {startup:.0f} s")
        pids = set()
        for session in sessions:
            for status in session.status():
                if status.state != "running" or status.pid is None:  # a running process has a pid
                    raise RuntimeError(f"{status.process} is {status.state}: {session.tail(status.process)}")
                pids.update(group_members(status.pid))
        for host in pool.hosts if pool is not None else []:
            pid = host.pid()
            if pid is None:
                raise RuntimeError(f"{host.name} is not running: {host.output.tail(20)}")
            pids.update(group_members(pid))
        # CPU the processes spent to get there: independent of DDS discovery jitter.
        startup_cpu = cpu_seconds(pids)
        time.sleep(SETTLE)
        pss = rss = 0
        for pid in pids:
            process_pss, process_rss = pss_and_rss(pid)
            pss += process_pss
            rss += process_rss
    finally:
        if pool is not None:
            pool.stop()
        for session in sessions:
            session.stop()
    probe.wait_gone({namespace for _, namespace in expected}, timeout=15)
    return {
        "robots": robots,
        "isolation": isolation,
        "processes": len(pids),
        "startup_s": startup,
        "startup_cpu_s": startup_cpu,
        "pss_mib_per_robot": pss / MIB / robots,
        "rss_mib_per_robot": rss / MIB / robots,
        "pss_mib_total": pss / MIB,
    }


def report(results: list[dict], info: dict[str, str], group_size: int) -> str:
    lines = [
        "# Isolation benchmark: `process` vs `robot` vs `agent`",
        "",
        "Produced by `bench/bench_isolation.py`. Each robot is one launch file with the fleet_nodes",
        "controller, battery and safety (parameters from a file, as rendered), started by the embedded",
        "runner, one LaunchSession per robot, in an isolated ROS domain (FastDDS, localhost).",
        f"With `agent` the fleet nodes are hosted by host processes of {group_size} robots each",
        "(fleet.runtime.hosting, as an agent runs them).",
        "",
        "- start-up: from the first `start()` until every node is in the ROS graph (probe node);",
        "  this includes FastDDS discovery, which adds a jitter of up to ~3 s (its announcement",
        "  period). Start-up CPU (user+system seconds the node processes had used when the graph",
        "  was complete) is the jitter-free measure of what starting costs.",
        "- memory: sum over all node processes, measured "
        f"{SETTLE:.0f} s after the graph is complete. **PSS** (shared pages split among the sharing",
        "  processes: the sum is the real cost) is the figure to compare; RSS (shared pages counted",
        "  in every process) is given for reference.",
        "",
        "Machine: " + ", ".join(f"{key} {value}" for key, value in info.items()) + ".",
        "The 2 cores are shared with other engineers' work, so start-up times carry noise.",
        "",
        "| robots | isolation | processes | start-up (s) | start-up per robot (s) | start-up CPU per robot (s) "
        "| PSS per robot (MiB) | RSS per robot (MiB) | PSS total (MiB) |",
        "|---:|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for row in results:
        lines.append(
            f"| {row['robots']} | {row['isolation']} | {row['processes']} | {row['startup_s']:.1f} | "
            f"{row['startup_s'] / row['robots']:.2f} | {row['startup_cpu_s'] / row['robots']:.2f} | "
            f"{row['pss_mib_per_robot']:.1f} | "
            f"{row['rss_mib_per_robot']:.1f} | {row['pss_mib_total']:.0f} |"
        )
    lines += ["", "Ratios to `process` of PSS per robot (`process` at the same size, else its largest run):", ""]
    by_key = {(row["robots"], row["isolation"]): row for row in results}  # last repeat
    process_runs = sorted(robots for robots, isolation in by_key if isolation == "process")
    for robots in sorted({row["robots"] for row in results}):
        reference = robots if robots in process_runs else (process_runs[-1] if process_runs else None)
        process = by_key.get((reference, "process")) if reference is not None else None
        for isolation in ("robot", "agent"):
            hosted = by_key.get((robots, isolation))
            if process and hosted:
                ratio = hosted["pss_mib_per_robot"] / process["pss_mib_per_robot"]
                speed = hosted["startup_s"] / process["startup_s"]
                cpu = hosted["startup_cpu_s"] / process["startup_cpu_s"]
                lines.append(
                    f"- {robots} robots, {isolation} (vs process at {reference}): memory (PSS) {ratio:.3f}x, "
                    f"start-up time {speed:.2f}x, start-up CPU per robot {cpu * reference / robots:.2f}x"
                )
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, nargs="+", default=[10, 30, 100])
    parser.add_argument("--isolation", nargs="+", default=["process", "robot", "agent"])
    parser.add_argument("--group-size", type=int, default=25, help="robots per host process (agent)")
    parser.add_argument(
        "--limit",
        nargs="*",
        default=["process=10", "robot=30"],
        metavar="ISOLATION=N",
        help="run an isolation only up to N robots (process: 120 s to 30 robots on 2 cores, or never)",
    )
    parser.add_argument("--repeat", type=int, default=1, help="runs of each case (all reported)")
    parser.add_argument(
        "--env",
        nargs="*",
        default=[],
        metavar="NAME=VALUE",
        help="extra environment of the node processes (e.g. MALLOC_ARENA_MAX=2)",
    )
    parser.add_argument("--output", type=Path, default=Path(__file__).parent / "results" / "isolation.md")
    args = parser.parse_args()
    compile_checkout()
    info = machine_info()
    limits = {name: int(value) for name, value in (item.split("=", 1) for item in args.limit)}
    results = []
    with tempfile.TemporaryDirectory(prefix="fleet-bench-") as workdir, reserve_domain_id() as domain:
        env = ros_environment(domain.domain_id)
        env.update(item.split("=", 1) for item in args.env)
        for key in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "RMW_IMPLEMENTATION"):
            os.environ[key] = env[key]  # the probe lives in this process
        probe = Probe()
        try:
            # Warm-up (page cache, .pyc files, the probe's own discovery); not reported.
            warm_dir = Path(workdir) / "warm-up"
            warm_dir.mkdir()
            run_case(1, "robot", warm_dir, env, probe)
            for robots in args.robots:
                for repeat in range(args.repeat):
                    for isolation in args.isolation:
                        if robots > limits.get(isolation, robots):
                            continue
                        case_dir = Path(workdir) / f"{isolation}-{robots}-{repeat}"
                        case_dir.mkdir()
                        row = run_case(robots, isolation, case_dir, env, probe, args.group_size)
                        results.append(row)
                        print(
                            f"{robots:>3} robots {isolation:<8} {row['processes']:>3} processes "
                            f"start-up {row['startup_s']:6.1f} s (cpu {row['startup_cpu_s']:6.1f} s)  "
                            f"PSS/robot {row['pss_mib_per_robot']:6.1f} MiB  "
                            f"RSS/robot {row['rss_mib_per_robot']:6.1f} MiB",
                            flush=True,
                        )
        finally:
            probe.close()
    if args.env:
        info["node environment"] = " ".join(args.env)
    text = report(results, info, args.group_size)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
