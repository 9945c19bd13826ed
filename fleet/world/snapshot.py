"""A top-down picture of the world from plain status data (no pybullet, no ROS).

`draw_snapshot(status, path)` takes the status document (status.py describes it) however it was
obtained (a local status file, or the agent running the world over Zenoh) and writes a PNG.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any


def _corners(x: float, y: float, yaw: float, length: float, width: float) -> list[tuple[float, float]]:
    c, s = math.cos(yaw), math.sin(yaw)
    return [
        (x + c * lx - s * ly, y + s * lx + c * ly)
        for lx, ly in (
            (length / 2, width / 2),
            (-length / 2, width / 2),
            (-length / 2, -width / 2),
            (length / 2, -width / 2),
        )
    ]


def draw_snapshot(
    status: dict[str, Any],
    path: str | Path,
    obstacles: list[dict[str, Any]] | None = None,
    title: str | None = None,
    size: float = 9.0,
) -> Path:
    """Write a PNG of obstacles, robots (name, heading, trail, lidar hits) and contacts."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Polygon

    obstacles = status.get("obstacles", []) if obstacles is None else obstacles
    robots: dict[str, Any] = status.get("robots") or {}
    fig, ax = plt.subplots(figsize=(size, size), dpi=110)
    xs: list[float] = []
    ys: list[float] = []

    for obstacle in obstacles:
        (ox, oy), yaw = obstacle["position"], obstacle.get("yaw", 0.0)
        if obstacle["type"] == "cylinder":
            r = obstacle["radius"]
            ax.add_patch(Circle((ox, oy), r, facecolor="#9e9e9e", edgecolor="#424242", zorder=1))
            xs += [ox - r, ox + r]
            ys += [oy - r, oy + r]
        else:
            corners = _corners(ox, oy, yaw, obstacle["size"][0], obstacle["size"][1])
            ax.add_patch(Polygon(corners, closed=True, facecolor="#9e9e9e", edgecolor="#424242", zorder=1))
            xs += [p[0] for p in corners]
            ys += [p[1] for p in corners]

    colors = plt.get_cmap("tab10" if len(robots) <= 10 else "tab20")
    placed = []  # (x, y, yaw, reach, color, label) drawn once the scale is known
    for i, (name, robot) in enumerate(sorted(robots.items())):
        color = colors(i % colors.N)
        pose = robot["pose"]
        x, y, yaw = pose["x"], pose["y"], pose["yaw"]
        hits = robot.get("scan_hits") or []
        if hits:
            ax.scatter(
                [h[0] for h in hits],
                [h[1] for h in hits],
                s=9,
                color=color,
                alpha=0.8,
                zorder=2,
                linewidths=0,
                label="lidar hits" if i == 0 else None,
            )
        trail = robot.get("trail") or []
        if len(trail) > 1:
            ax.plot(
                [p[0] for p in trail] + [x],
                [p[1] for p in trail] + [y],
                color=color,
                alpha=0.6,
                linewidth=1.2,
                linestyle="--",
                zorder=3,
                label="trail" if i == 0 else None,
            )
        model = robot.get("model") or {"radius": 0.2}
        if "radius" in model:
            reach = model["radius"]
            ax.add_patch(Circle((x, y), reach, facecolor=color, edgecolor="black", alpha=0.9, zorder=4))
        else:
            reach = max(model["length"], model["width"]) / 2
            ax.add_patch(
                Polygon(
                    _corners(x, y, yaw, model["length"], model["width"]),
                    closed=True,
                    facecolor=color,
                    edgecolor="black",
                    alpha=0.9,
                    zorder=4,
                )
            )
        battery = robot.get("battery")
        label = name if battery is None else f"{name} ({battery * 100:.0f}%)"
        placed.append((x, y, yaw, reach, label))
        xs += [x - reach, x + reach] + [h[0] for h in hits] + [p[0] for p in trail]
        ys += [y - reach, y + reach] + [h[1] for h in hits] + [p[1] for p in trail]

    span = 2.0
    if xs:
        margin = 0.5
        x0, x1, y0, y1 = min(xs) - margin, max(xs) + margin, min(ys) - margin, max(ys) + margin
        span = max(x1 - x0, y1 - y0)
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        ax.set_xlim(cx - span / 2, cx + span / 2)
        ax.set_ylim(cy - span / 2, cy + span / 2)
    above: list[tuple[float, float]] = []  # anchors of the labels drawn above their robot
    for x, y, yaw, reach, label in placed:
        # Heading arrows and labels sized to the picture, so they read at any world size.
        arrow = max(reach * 1.6, span * 0.035)
        ax.annotate(
            "",
            xy=(x + arrow * math.cos(yaw), y + arrow * math.sin(yaw)),
            xytext=(x, y),
            arrowprops={"arrowstyle": "-|>", "color": "black", "lw": 1.5, "mutation_scale": 14},
            zorder=5,
        )
        # Robots side by side (touching, say) would get their labels on top of each other: the
        # second one goes below its robot.
        crowded = any(abs(x - lx) < span * 0.15 and abs(y + reach - ly) < span * 0.04 for lx, ly in above)
        if not crowded:
            above.append((x, y + reach))
        ax.annotate(
            label,
            (x, y - reach if crowded else y + reach),
            xytext=(0, -6 if crowded else 6),
            textcoords="offset points",
            ha="center",
            va="top" if crowded else "bottom",
            fontsize=7 if len(placed) > 20 else 9,
            zorder=6,
            bbox={"boxstyle": "round,pad=0.2", "facecolor": "white", "alpha": 0.75, "linewidth": 0},
        )
    if placed:
        ax.legend(loc="upper right", fontsize=8, framealpha=0.8)
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    contacts = (status.get("contacts") or {}).get("count", 0)
    heading = title or (
        f"{status.get('fleet', 'world')}: t = {status.get('sim_time', 0):.1f} s, "
        f"RTF {status.get('real_time_factor', 0):.2f}, {len(robots)} robots, "
        f"{contacts} contact{'' if contacts == 1 else 's'}"
    )
    ax.set_title(heading)
    errors = status.get("errors") or []
    if errors:
        text = "\n".join(e.get("message", str(e)) if isinstance(e, dict) else str(e) for e in errors[:5])
        fig.text(0.01, 0.01, text, fontsize=7, color="#b71c1c", va="bottom")
    path = Path(path)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)
    return path
