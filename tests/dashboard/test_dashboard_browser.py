"""`fleet dashboard` in a real headless browser (Playwright driving the system Chromium) on
fleets/two_robots.yaml deployed for real: the page shows both robots, follows a moving robot
within a second, shows a killed node's restart, and a robot's logs and parameters on click;
and a fleet without a world."""

from __future__ import annotations

import math
import os
import re
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import pytest
import yaml

from fleet.testing import running_fleet

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[2]
TWO_ROBOTS = REPO / "fleets" / "two_robots.yaml"
ROBOTS = ("robot1", "robot2")
CHROMIUM = Path("/usr/bin/chromium")  # Debian's `chromium` (README: Run the tests)
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
URL_LINE = re.compile(r"fleet dashboard on (http://\S+)")


@contextmanager
def dashboard(fleet, log: Path):
    """`fleet dashboard --port 0` as a user starts it, connected to the fleet's router; its URL."""
    command = [sys.executable, "-m", "fleet", "dashboard", "--port", "0", "--connect", fleet.endpoint]
    with open(log, "wb") as errors:
        process = subprocess.Popen(command, env=fleet.env, stdout=subprocess.PIPE, stderr=errors, text=True)
    output = process.stdout
    assert output is not None
    try:
        line = output.readline()
        match = URL_LINE.search(line)
        assert match, f"no URL printed: {line!r}\n{log.read_text()}"
        yield match.group(1)
        process.send_signal(signal.SIGINT)  # Ctrl-C: a clean stop
        assert process.wait(timeout=20) == 0, log.read_text()
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        output.close()


@contextmanager
def browser_page(profile: Path):
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        context = playwright.chromium.launch_persistent_context(
            str(profile), executable_path=str(CHROMIUM), headless=True, args=CHROMIUM_ARGS
        )
        try:
            page = context.pages[0] if context.pages else context.new_page()
            page.set_viewport_size({"width": 1400, "height": 900})
            yield page
        finally:
            context.close()


def page_pose(page, robot: str) -> tuple[float, float, float]:
    """The pose the page's table shows (x, y, yaw); fails the test when it shows none."""
    text = page.locator(f'#robots tr[data-robot="{robot}"] td.pose').text_content() or ""
    parts = [float(part) for part in text.split(",")] if text else []
    assert len(parts) == 3, f"no pose shown for {robot}: {text!r}"
    return parts[0], parts[1], parts[2]


def cell(page, robot: str, column: str) -> str:
    return page.locator(f'#robots tr[data-robot="{robot}"] td.{column}').text_content() or ""


@pytest.fixture(scope="module")
def two_robots(tmp_path_factory):
    if not CHROMIUM.exists():
        pytest.fail(f"{CHROMIUM} is missing: install Debian's chromium (see README, Run the tests)")
    with running_fleet(TWO_ROBOTS, directory=tmp_path_factory.mktemp("two_robots")) as fleet:
        yield fleet


def test_dashboard_shows_the_fleet_live(two_robots, tmp_path):
    from playwright.sync_api import expect

    fleet = two_robots
    with dashboard(fleet, tmp_path / "dashboard.log") as url, browser_page(tmp_path / "profile") as page:
        assert url.startswith("http://127.0.0.1:")
        page.goto(url)
        expect(page.locator("#connection")).to_have_text("live", timeout=10_000)

        # Both robots: in the table, running, and on the map with their names; the world's obstacles.
        for robot in ROBOTS:
            expect(page.locator(f'#robots tr[data-robot="{robot}"] td.state')).to_have_text("running", timeout=30_000)
            expect(page.locator(f'#map g.robot[data-robot="{robot}"]')).to_be_visible()
            expect(page.locator("#map text.label", has_text=robot)).to_be_visible()
        expect(page.locator("#map [data-obstacle]")).to_have_count(3)
        expect(page.locator('#agents tr[data-agent="local"] td.state')).to_have_text("online")
        expect(page.locator('#agents tr[data-agent="local"] td.up')).to_have_text(re.compile(r"^\d+(\.\d)? (s|min|h)$"))
        expect(page.locator(f'#history tr[data-generation="{fleet.generation}"]')).to_have_count(1)
        assert "cmd_vel" in cell(page, "robot1", "flow")

        # robot1 drives: its pose on the page changes, and is never more than a second behind
        # the world (robot1 drives at most 0.4 m/s).
        first = page_pose(page, "robot1")
        fleet.wait_for(
            lambda: math.dist(page_pose(page, "robot1")[:2], first[:2]) > 0.2,
            sim_timeout=20,
            what="robot1's pose on the page to change",
            explain=lambda: f"page: {page_pose(page, 'robot1')}, world: {fleet.pose('robot1')}",
        )
        for _ in range(5):
            shown = page_pose(page, "robot1")
            world = fleet.pose("robot1")
            assert world.distance_to(shown[:2]) < 0.45, (shown, world)
            time.sleep(0.5)
        on_map = page.locator('#map g.robot[data-robot="robot1"]')
        expect(on_map).not_to_have_attribute("transform", on_map.get_attribute("transform"), timeout=2_000)

        # Click robot2: its nodes with their pids, its parameters as deployed (max_speed 0.8 is
        # its own override), read live from the node on request, and its logs.
        page.locator('#robots tr[data-robot="robot2"]').click()
        expect(page.locator("#detail-title")).to_contain_text("robot2")
        for node in ("controller", "battery", "safety"):
            expect(page.locator(f'#nodes tr[data-node="{node}"] td.state')).to_have_text("running")
        max_speed = page.locator('#params tr[data-node="controller"][data-param="max_speed"]')
        expect(max_speed.locator("td.deployed")).to_have_text("0.8", timeout=10_000)
        max_speed.locator("button").click()
        expect(max_speed.locator("td.live")).to_have_text("0.8", timeout=40_000)
        # Values are written as everywhere in fleet (ROS's YAML), doubles with their point: a user
        # copying [0, 2, ...] into a spec would give the node integers, which it refuses.
        waypoints = page.locator('#params tr[data-node="controller"][data-param="waypoints"]')
        expect(waypoints.locator("td.deployed")).to_have_text("[0.0, 2.0, -1.0, 2.0, -1.0, 0.0, 0.0, 0.0]")
        waypoints.locator("button").click()
        expect(waypoints.locator("td.live")).to_have_text("[0.0, 2.0, -1.0, 2.0, -1.0, 0.0, 0.0, 0.0]", timeout=40_000)
        capacity = page.locator('#params tr[data-node="battery"][data-param="capacity"]')
        expect(capacity.locator("td.deployed")).to_have_text("50.0")
        expect(page.locator("#logs")).not_to_have_text(re.compile(r"^(loading\.\.\.|\(no log lines\))?$"))
        assert "cannot read" not in (page.locator("#logs").text_content() or "")

        # SIGKILL robot2's controller (its pid from status): the page shows the restart, with
        # the new pid, within a second of status saying so.
        restarts = int(cell(page, "robot2", "restarts"))
        pid = fleet.node_pid("robot2", "controller")
        expect(page.locator('#nodes tr[data-node="controller"] td.pid')).to_have_text(str(pid))
        os.kill(pid, signal.SIGKILL)
        fleet.wait_for(
            lambda: fleet.robot_status("robot2").restarts > restarts,
            timeout=20,
            what="status to report robot2's controller restarted",
        )
        seen_by_status = time.monotonic()
        expect(page.locator('#robots tr[data-robot="robot2"] td.restarts')).to_have_text(
            str(restarts + 1), timeout=5_000
        )
        assert time.monotonic() - seen_by_status < 1.5
        new_pid = fleet.wait_for(
            lambda: fleet.node_pid("robot2", "controller") if fleet.robot_status("robot2").running == 3 else None,
            timeout=20,
            what="robot2's controller running again",
        )
        assert new_pid != pid
        expect(page.locator('#nodes tr[data-node="controller"] td.pid')).to_have_text(str(new_pid), timeout=5_000)
        expect(page.locator('#nodes tr[data-node="controller"] td.restarts')).to_have_text("1")


def test_a_fleet_without_a_world_is_shown_as_such(tmp_path):
    """Real robots run no world: the map says there is none to draw (it said the world had not
    reported yet, as if one were coming), and the robots' table is there as for any fleet."""
    from playwright.sync_api import expect

    spec = tmp_path / "real_robots.yaml"
    data = yaml.safe_load(TWO_ROBOTS.read_text())
    data.pop("world")
    data["fleet"] = "real_robots"
    data["ros"]["use_sim_time"] = False
    data["defaults"]["isolation"] = "agent"
    spec.write_text(yaml.safe_dump(data))
    with (
        running_fleet(spec, directory=tmp_path / "fleet") as fleet,
        dashboard(fleet, tmp_path / "dashboard.log") as url,
        browser_page(tmp_path / "profile") as page,
    ):
        page.goto(url)
        expect(page.locator("#connection")).to_have_text("live", timeout=10_000)
        for robot in ROBOTS:
            expect(page.locator(f'#robots tr[data-robot="{robot}"] td.state')).to_have_text("running", timeout=30_000)
        expect(page.locator("#world-line")).to_have_text(
            "fleet real_robots runs no world: its robots are not simulated, so there is no map"
        )
        expect(page.locator("#map g.robot")).to_have_count(0)
