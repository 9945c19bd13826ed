"""The data plane: latency, throughput and discovery of ROS topics that cross computers.

Two "computers" are network namespaces on one bridge (fleet.testing.netns; needs root); "one
computer" is both sides in this machine's own namespace.  Every participant is a discovery
client of a Fast DDS discovery server (the `dds` transport), except where LOCALHOST discovery
is measured for comparison.  Runs:

- the same over the `zenoh` transport (a router on one computer, a bridge on each), with the
  bridges' CPU per robot;
- latency: one robot's odometry (50 Hz, reliable), one-way p50/p99 from header stamps;
- throughput: 100 robots' odometry (50 Hz, reliable) and scans (10 Hz, 360 beams, best effort)
  from one process to another: delivered fraction and latency;
- world RTF: 100 light robots as fast as possible, their topics taken on the same or the other
  computer;
- discovery: 30 robot participants and a world participant: seconds until the world has
  matched every robot's subscription (LOCALHOST on one computer, discovery server on one and
  across two, LOCALHOST with ROS_STATIC_PEERS across two).

Usage: .venv/bin/python bench/bench_dataplane.py [--seconds 20] [--output bench/results/dataplane.md]
       [--only zenoh] [--robots 100] [--bridge-from CHECKOUT] [--latency-pairs N]

--only zenoh measures the zenoh transport's flows alone; --robots picks the flows' sizes;
--bridge-from runs the bridges and router of another checkout (with its .venv) (a before/after pair on one machine).
--latency-pairs N measures only what the zenoh transport adds to one robot's latency: N pairs of
flows, `dds` across the veth link then `zenoh`, each pair's difference of p50s, written to
bench/results/dataplane_latency.md (pairs, because single runs drift with the machine's load).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.bytecode import compile_checkout
from bench.dataplane_peer import ODOM_RATE
from bench.machine import machine_description
from fleet.dataplane.discovery import server_command, server_environment
from fleet.runtime.environment import discovery_server_port, ros_environment
from fleet.runtime.processes import ServiceProcess
from fleet.testing.isolation import reserve_domain_id
from fleet.testing.netns import Lan, netns_problem
from fleet.wire.protocol import TopicRoute

PEER = [sys.executable, str(Path(__file__).resolve().parent / "dataplane_peer.py")]


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))] if ordered else float("nan")


class Setup:
    """Where the sides run: `prefix_a`/`prefix_b` wrap commands (ip netns exec, or nothing)."""

    def __init__(self, name: str, domain: int, lan: Lan | None, discovery: bool = True, static_peers: bool = False):
        self.name, self.lan = name, lan
        address = lan.hosts["sim"].address if lan else "127.0.0.1"
        self.server = f"{address}:{discovery_server_port(domain)}" if discovery else None
        self.env = ros_environment(domain, discovery_server=self.server)
        self.env_b = dict(self.env)
        if static_peers and lan:  # LOCALHOST plus the other computer's address, each way
            self.env["ROS_STATIC_PEERS"] = lan.hosts["rack"].address
            self.env_b["ROS_STATIC_PEERS"] = lan.hosts["sim"].address
        self.ds = None
        if self.server:
            log_file = Path(tempfile.mkdtemp()) / "ds.log"
            command = server_command(self.server, log_file.with_suffix(".xml"))
            if lan:  # the server runs on "sim"
                command = lan.hosts["sim"].command(*command)
            self.ds = ServiceProcess(command, server_environment(ros_environment(domain)), log_file)
            self.ds.keep_running()
            time.sleep(0.5)

    def side(self, which: str, *args: str) -> list[str]:
        command = [*PEER, *args]
        if self.lan is None:
            return command
        return self.lan.hosts["sim" if which == "a" else "rack"].command(*command)

    def prepare(self, robots: int) -> None:
        """Before a flow of `robots` robots (the zenoh setup starts its bridges here)."""

    def finish(self) -> float | None:
        """After a flow: CPU seconds its bridges used (None: no bridges)."""
        return None

    def bridged(self) -> float | None:
        """After a flow: messages the importing bridge published over those the exporting one
        sent (None: no bridges): what was lost between the bridges, apart from DDS on either side."""
        return None

    def close(self) -> None:
        if self.ds:
            self.ds.stop()


class ZenohSetup(Setup):
    """The `zenoh` transport on two computers: DDS on each computer's loopback (a discovery server
    each), a router on sim, a bridge on each side carrying the robots' topics rack -> sim."""

    def __init__(self, name: str, domain: int, lan: Lan, bridge_from: Path | None = None):
        self.name, self.domain = name, domain
        self.bridge_env = dict(ros_environment(domain, discovery_server=f"127.0.0.1:{discovery_server_port(domain)}"))
        # The other checkout's own interpreter (this one's editable install would win over
        # PYTHONPATH), with -P: `-m` would otherwise find this checkout's fleet/ in the working directory.
        self.python = (
            [str(bridge_from.resolve() / ".venv" / "bin" / "python"), "-P"] if bridge_from else [sys.executable]
        )
        self.lan: Lan = lan  # never None here: the transport needs two computers
        self.server = f"127.0.0.1:{discovery_server_port(domain)}"
        self.env = self.env_b = ros_environment(domain, discovery_server=self.server)
        self.tmp = Path(tempfile.mkdtemp())
        self.servers = [
            ServiceProcess(
                lan.hosts[host].command(*server_command(self.server, self.tmp / f"ds-{host}.xml")),
                server_environment(ros_environment(domain)),
                self.tmp / f"ds-{host}.log",
            )
            for host in ("sim", "rack")
        ]
        self.endpoint = f"tcp/{lan.hosts['sim'].address}:7447"
        router = [
            *self.python,
            "-m",
            "fleet",
            "router",
            "--listen",
            self.endpoint,
            "--state-dir",
            str(self.tmp / "router"),
        ]
        self.servers.append(
            ServiceProcess(lan.hosts["sim"].command(*router), dict(os.environ), self.tmp / "router.log")
        )
        for service in self.servers:
            service.keep_running()
        time.sleep(2.0)
        self.ds = None
        self.bridges: list[ServiceProcess] = []
        self.robots = 0

    def prepare(self, robots: int) -> None:
        self.robots = robots
        routes = [
            # depth: the sender's (dataplane_peer), as fleet's routes carry the publisher's QoS
            TopicRoute(name=f"/r{k}/{topic}", type=kind, reliable=reliable, depth=100)
            for k in range(robots)
            for topic, kind, reliable in (
                ("odom", "nav_msgs/msg/Odometry", True),
                ("scan", "sensor_msgs/msg/LaserScan", False),
            )
        ]
        for host, direction in (("rack", "exports"), ("sim", "imports")):
            config = self.tmp / f"bridge-{host}-{robots}.json"
            config.write_text(
                json.dumps(
                    {
                        "fleet": "bench",
                        "agent": host,
                        "connect": [self.endpoint],
                        "zenoh_config": None,
                        "exports": [],
                        "imports": [],
                        direction: [route.model_dump() for route in routes],
                    }
                )
            )
            command = self.lan.hosts[host].command(*self.python, "-m", "fleet.dataplane.bridge", str(config))
            bridge = ServiceProcess(command, self.bridge_env, self.tmp / f"bridge-{host}-{robots}.log")
            bridge.keep_running()
            self.bridges.append(bridge)
        time.sleep(3.0)  # bridges up: sessions open, endpoints declared

    def finish(self) -> float | None:
        used = 0.0
        for bridge in self.bridges:
            times = psutil.Process(bridge.pid).cpu_times()
            used += times.user + times.system
            bridge.stop()
        self.bridges = []
        return used

    def bridged(self) -> float | None:
        # The last line of each bridge's log counts its messages ("stopping: N messages out, M in").
        counts = {}
        for host in ("rack", "sim"):
            log = (self.tmp / f"bridge-{host}-{self.robots}.log").read_text()
            found = re.findall(r"stopping: (\d+) messages out, (\d+) in", log)
            counts[host] = tuple(map(int, found[-1])) if found else (0, 0)
        out, received = counts["rack"][0], counts["sim"][1]
        return received / out if out else None

    def close(self) -> None:
        for service in self.bridges + self.servers:
            service.stop()


RECEIVERS = {1: 1, 100: 4}  # robots -> receiving processes (a robot's data goes to its own processes)


def flow(setup: Setup, robots: int, seconds: float, odom_rate: int = ODOM_RATE) -> dict:
    setup.prepare(robots)
    started = time.monotonic()
    share = robots // RECEIVERS[robots]
    receivers = [
        subprocess.Popen(
            setup.side("a", "receive", str(share), str(seconds), str(first)),
            env=setup.env,
            stdout=subprocess.PIPE,
            text=True,
        )
        for first in range(0, robots, share)
    ]
    sender = subprocess.Popen(
        setup.side("b", "send", str(robots), str(seconds), "0", str(odom_rate)),
        env=setup.env_b,
        stdout=subprocess.PIPE,
        text=True,
    )
    sent_out, _ = sender.communicate(timeout=seconds + 120)
    sent = json.loads(sent_out.strip().splitlines()[-1])
    latencies, received = [], {"odom": 0, "scan": 0}
    for receiver in receivers:
        out, _ = receiver.communicate(timeout=120)
        data = json.loads(out.strip().splitlines()[-1])
        latencies += data["latencies_ms"]
        for kind in received:
            received[kind] += data["counts"][kind]
    cpu = setup.finish()
    return {
        "bridge_cpu_per_robot": None if cpu is None else cpu / (time.monotonic() - started) / robots,
        "bridged": setup.bridged(),
        "p50": percentile(latencies, 0.5),
        "p99": percentile(latencies, 0.99),
        "rate": sent["odom_rate"],
        "odom": received["odom"] / sent["sent"]["odom"],
        "scan": received["scan"] / sent["sent"]["scan"],
    }


def discovery(setup: Setup, robots: int, where: str) -> float | None:
    """Seconds from launching the robot participants until the world participant matched them all."""
    observer = subprocess.Popen(
        setup.side("a", "observe", str(robots), "120"), env=setup.env, stdout=subprocess.PIPE, text=True
    )
    assert observer.stdout is not None
    observer.stdout.readline()  # ready: its own start-up is not counted
    launched = time.time()
    participants = [
        subprocess.Popen(setup.side(where, "participant", str(k), "130"), env=setup.env_b, stdout=subprocess.DEVNULL)
        for k in range(robots)
    ]
    out, _ = observer.communicate(timeout=200)
    for process in participants:  # SIGTERM: rclpy shuts down; what Fast DDS still leaves, measure_discovery cleans
        process.terminate()
    for process in participants:
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    at = json.loads(out.strip().splitlines()[-1]).get("converged_at")
    return None if at is None else at - launched


WORLD_BENCH = Path(__file__).resolve().parent / "bench_world.py"


def world_rtf(setup: Setup, robots: int, sim: float, where: str) -> float | None:
    """RTF of a world of `robots` light robots on sim (as fast as possible, bench_world's child)
    while four processes on `where` ("a": the same computer, "b": the other) take every robot's
    odometry and scans."""
    share = robots // 4
    receivers = [
        subprocess.Popen(
            setup.side(where, "receive", str(share), str(sim), str(first), "robot"),
            env=setup.env_b,
            stdout=subprocess.PIPE,
            text=True,
        )
        for first in range(1, robots + 1, share)
    ]
    time.sleep(3.0)
    command = [sys.executable, str(WORLD_BENCH), "--child", "light", str(robots), str(sim)]
    if setup.lan is not None:
        command = setup.lan.hosts["sim"].command(*command)
    done = subprocess.run(command, env=setup.env, capture_output=True, text=True, timeout=900)
    for receiver in receivers:
        receiver.communicate(timeout=200)
    for line in done.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])["rtf"]
    return None


def measure_world(domain: int, lan: Lan) -> list[tuple[str, float | None]]:
    setup = Setup("world", domain, lan)
    rows = []
    try:
        for label, where in (
            ("world and robots' subscribers on one computer", "a"),
            ("subscribers on the other computer", "b"),
        ):
            rtf = world_rtf(setup, 100, 20.0, where)
            print(label, rtf, flush=True)
            rows.append((label, rtf))
    finally:
        setup.close()
    return rows


def measure_discovery(domain: int, lan: Lan) -> list[tuple[str, float | None]]:
    rows = []
    for label, network, with_server, static in (
        ("one computer, LOCALHOST", None, False, False),
        ("one computer, discovery server", None, True, False),
        ("two computers, discovery server", lan, True, False),
        ("two computers, LOCALHOST + ROS_STATIC_PEERS", lan, False, True),
    ):
        setup = Setup(label, domain, network, discovery=with_server, static_peers=static)
        try:
            converged = discovery(setup, 30, "b")
        finally:
            setup.close()
        print(label, converged, flush=True)
        rows.append((label, converged))
    # LOCALHOST participants map shared memory, and Fast DDS leaves some of it in /dev/shm even
    # after a clean exit: remove what belongs to no living process (the wheels' own tool).
    fastdds = Path(sys.executable).parent / "fastdds"
    subprocess.run([str(fastdds), "shm", "clean"], capture_output=True, check=False)
    return rows


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--output", type=Path, default=Path(__file__).resolve().parent / "results" / "dataplane.md")
    parser.add_argument("--only", choices=["zenoh"], help="only the zenoh transport's flows")
    parser.add_argument("--robots", type=int, action="append", choices=sorted(RECEIVERS), help="flow sizes")
    parser.add_argument("--bridge-from", type=Path, help="run the bridges and router of this checkout")
    parser.add_argument("--latency-pairs", type=int, help="only one robot's latency, dds then zenoh, N times")
    parser.add_argument("--odom-rate", type=int, default=ODOM_RATE, help="the latency pairs' odometry rate (Hz)")
    args = parser.parse_args()
    compile_checkout()
    if args.bridge_from:
        compile_checkout(args.bridge_from.resolve())
    problem = netns_problem()
    if problem:
        print(f"bench_dataplane: {problem}", file=sys.stderr)
        return 2
    if args.latency_pairs:
        output = args.output.with_name("dataplane_latency.md") if args.output.name == "dataplane.md" else args.output
        return latency_pairs(args.latency_pairs, args.seconds, args.odom_rate, args.bridge_from, output)
    sizes = args.robots or sorted(RECEIVERS)
    setups = (("one computer", False), ("two computers (veth)", True), ("two computers, zenoh", True))
    rows_flow, rows_discovery, rows_rtf = [], [], []
    with reserve_domain_id() as reservation, Lan(["sim", "rack"]) as lan:
        domain = reservation.domain_id
        for label, two in setups:
            if args.only and args.only not in label:
                continue
            setup: Setup
            if "zenoh" in label:
                setup = ZenohSetup(label, domain, lan, args.bridge_from)
            else:
                setup = Setup(label, domain, lan if two else None)
            try:
                for robots in sizes:
                    result = flow(setup, robots, args.seconds)
                    print(label, robots, result, flush=True)
                    rows_flow.append((label, robots, result))
            finally:
                setup.close()
        if not args.only:
            rows_rtf = measure_world(domain, lan)
            rows_discovery = measure_discovery(domain, lan)
    lines = [
        "# Data plane: topics across computers (`dds` and `zenoh` transports)",
        "",
        f"Machine: {machine_description()}.",
        f"Command: `.venv/bin/python bench/bench_dataplane.py {' '.join(sys.argv[1:])}`.",
        "",
        "One sender process publishes every robot's topics; with 100 robots, four receiver processes",
        "take 25 robots each. Delivered: messages received over messages published. Latency is one-way",
        "and includes any queueing in the receivers.",
        "",
        "Bridge CPU: CPU time of both bridges (zenoh transport) over the run, per robot, in % of one core.",
        "Through the bridges: messages the importing bridge published over those the exporting bridge",
        "sent (from their logs); the rest of the loss is in DDS on either side.",
        "",
        "| where | robots | sender odom rate (Hz) | latency p50 (ms) | p99 (ms) | odom delivered (reliable) | scans delivered (best effort) | bridge CPU per robot | through the bridges |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for label, robots, r in rows_flow:
        cpu, bridged = r["bridge_cpu_per_robot"], r["bridged"]
        lines.append(
            f"| {label} | {robots} | {r['rate']:.1f} | {r['p50']:.2f} | {r['p99']:.2f} | {r['odom']:.1%} | "
            f"{r['scan']:.1%} | {'' if cpu is None else f'{cpu:.2%}'} | {'' if bridged is None else f'{bridged:.1%}'} |"
        )
    if rows_discovery:
        lines += discovery_lines(rows_discovery)
    if rows_rtf:
        lines += world_lines(rows_rtf)
    args.output.write_text("\n".join(lines) + "\n")
    print(f"wrote {args.output}")
    return 0


def latency_pairs(pairs: int, seconds: float, odom_rate: int, bridge_from: Path | None, output: Path) -> int:
    """One robot's odometry across the veth link, `dds` then `zenoh`, `pairs` times: what the
    zenoh transport adds at p50, pair by pair."""
    rows = []
    with reserve_domain_id() as reservation, Lan(["sim", "rack"]) as lan:
        domain = reservation.domain_id
        for _ in range(pairs):
            p50s = []
            for make in (
                lambda: Setup("two computers (veth)", domain, lan),
                lambda: ZenohSetup("two computers, zenoh", domain, lan, bridge_from),
            ):
                setup = make()
                try:
                    p50s.append(flow(setup, 1, seconds, odom_rate)["p50"])
                finally:
                    setup.close()
            rows.append((p50s[0], p50s[1]))
            print(f"dds {p50s[0]:.2f} ms, zenoh {p50s[1]:.2f} ms: adds {p50s[1] - p50s[0]:.2f} ms", flush=True)
    added = sorted(zenoh - dds for dds, zenoh in rows)
    lines = [
        "# Data plane: what the zenoh transport adds to one robot's latency",
        "",
        f"Machine: {machine_description()}.",
        f"Command: `.venv/bin/python bench/bench_dataplane.py {' '.join(sys.argv[1:])}`.",
        "",
        f"One robot's odometry ({odom_rate} Hz, reliable) from one computer to the other for {seconds:g} s,",
        "over `dds` and then over `zenoh`, in turn; one-way p50 in ms.",
        "",
        "| pair | dds p50 | zenoh p50 | zenoh adds |",
        "|---|---|---|---|",
        *(f"| {n} | {dds:.2f} | {zenoh:.2f} | {zenoh - dds:.2f} |" for n, (dds, zenoh) in enumerate(rows, 1)),
        "",
        f"Median added: **{statistics.median(added):.2f} ms** (range {added[0]:.2f} to {added[-1]:.2f}).",
    ]
    output.write_text("\n".join(lines) + "\n")
    print(f"wrote {output}")
    return 0


def discovery_lines(rows_discovery: list[tuple[str, float | None]]) -> list[str]:
    lines = [
        "",
        "Discovery of 30 robot participants by a world participant:",
        "",
        "| setup | seconds to match all |",
        "|---|---|",
    ]
    for label, converged in rows_discovery:
        lines.append(f"| {label} | {'not converged in 120 s' if converged is None else f'{converged:.1f}'} |")
    return lines


def world_lines(rows_rtf: list[tuple[str, float | None]]) -> list[str]:
    lines = [
        "",
        "World with 100 light robots (as fast as possible, 20 s of sim time, `dds`), every robot's",
        "odometry and scans taken by four subscriber processes:",
        "",
        "| where the subscribers run | RTF |",
        "|---|---|",
    ]
    for label, rtf in rows_rtf:
        lines.append(f"| {label} | {'failed' if rtf is None else f'{rtf:.2f}'} |")
    return lines


if __name__ == "__main__":
    sys.exit(main())
