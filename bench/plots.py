"""Figures of the benchmark results: time and memory against robots, as PNG beside the tables.

Reads the markdown tables the benchmarks wrote to bench/results (the tables are the data; a
figure only draws them) and writes bench/results/*.png, each captioned with the machine and the
load average its table was measured under.  Needs matplotlib (the `bench` extra).

    .venv/bin/python bench/plots.py
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # after choosing the file backend
from matplotlib.ticker import FuncFormatter, NullFormatter

RESULTS = Path(__file__).resolve().parent / "results"


def tables(path: Path) -> list[list[dict[str, str]]]:
    """Every markdown table of a file, as rows of {header: cell} (bold marks removed)."""
    found: list[list[dict[str, str]]] = []
    header: list[str] | None = None
    for line in [*path.read_text().splitlines(), ""]:
        if not line.startswith("|"):
            header = None
            continue
        cells = [cell.strip().replace("**", "") for cell in line.strip().strip("|").split("|")]
        if header is None:
            header = cells
            found.append([])
        elif not set("".join(cells)) <= set("-: "):
            found[-1].append(dict(zip(header, cells, strict=False)))
    return found


def number(text: str) -> float | None:
    match = re.match(r"-?[0-9]+(\.[0-9]+)?", text.replace(",", ""))
    return float(match.group()) if match else None


def conditions(path: Path) -> str:
    """The machine line of a results file (it names the load average), for a caption."""
    for line in path.read_text().splitlines():
        if "load" in line and ("Machine" in line or "Measured" in line):
            return line.strip().removeprefix("Machine: ")[:230]
    return ""


def series(rows: list[dict[str, str]], key: str, x: str, y: str) -> dict[str, tuple[list[float], list[float]]]:
    """Points (x, y) per value of column `key`, rows without numbers left out."""
    out: dict[str, tuple[list[float], list[float]]] = {}
    for row in rows:
        xv, yv = number(row.get(x, "")), number(row.get(y, ""))
        if xv is not None and yv is not None:
            xs, ys = out.setdefault(row.get(key, ""), ([], []))
            xs.append(xv)
            ys.append(yv)
    return out


def figure(path: Path, title: str, caption: str, panels: list[tuple[str, dict, str | None, float | None]]) -> None:
    """One PNG of side-by-side panels (y label, {label: (xs, ys)}, y scale, target line)."""
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 4.4), squeeze=False)
    for ax, (ylabel, lines, yscale, target) in zip(axes[0], panels, strict=True):
        for label, (xs, ys) in lines.items():
            ax.plot(xs, ys, marker="o", label=label)
        if target is not None:
            ax.axhline(target, color="grey", linestyle="--", linewidth=1, label=f"target {target:g}")
        ax.set_xscale("log")
        if yscale:
            ax.set_yscale(yscale)
        for axis in (ax.xaxis, ax.yaxis) if yscale == "log" else (ax.xaxis,):
            # plain numbers (30, 60, 100) instead of 3x10^1, and no labels on minor ticks, which collide
            axis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
            axis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("robots")
        ax.set_ylabel(ylabel)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(title)
    fig.text(0.01, 0.01, caption, fontsize=7, wrap=True)
    fig.tight_layout(rect=(0, 0.06, 1, 0.95))
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote {path}")


def world() -> None:
    source = RESULTS / "world.md"
    if not source.exists():
        return
    rows = tables(source)[0]
    figure(
        RESULTS / "world.png",
        "Shared world: real-time factor and memory against robots",
        f"{source.name}: {conditions(source)}",
        [
            ("real-time factor (sim s / wall s)", series(rows, "model", "robots", "RTF"), "log", 1.0),
            ("RSS of the world's processes (MiB)", series(rows, "model", "robots", "RSS MiB"), None, None),
        ],
    )
    compare = RESULTS / "world_compare.md"
    if compare.exists():
        rows = tables(compare)[0]
        lines: dict[str, tuple[list[float], list[float]]] = {}
        for row in rows:
            for when, column in (("before", "RTF before (median)"), ("after", "RTF after (median)")):
                xs, ys = lines.setdefault(f"{row['model']} {when}", ([], []))
                xs.append(float(row["robots"]))
                ys.append(float(row[column]))
        figure(
            RESULTS / "world_compare.png",
            "Shared world before and after, run in turn",
            f"{compare.name}: {conditions(compare)}",
            [("real-time factor (median)", lines, "log", 1.0)],
        )


def isolation() -> None:
    source = RESULTS / "isolation.md"
    if not source.exists():
        return
    rows = tables(source)[0]
    figure(
        RESULTS / "isolation.png",
        "Robots' nodes: memory and start-up against robots, per isolation",
        f"{source.name}: {conditions(source)}",
        [
            ("PSS per robot (MiB)", series(rows, "isolation", "robots", "PSS per robot (MiB)"), "log", None),
            ("start-up until all nodes are seen (s)", series(rows, "isolation", "robots", "start-up (s)"), "log", None),
        ],
    )


def expansion() -> None:
    source = RESULTS / "expand_scaling.md"
    if not source.exists():
        return
    rows = tables(source)[0]
    figure(
        RESULTS / "expand_scaling.png",
        "fleet render --json: time against robots",
        f"{source.name}: {conditions(source)}",
        [
            (
                "seconds (median)",
                {
                    "wall": series(rows, "", "robots", "wall median (s)")[""],
                    "CPU": series(rows, "", "robots", "CPU median (s)")[""],
                },
                None,
                None,
            )
        ],
    )


def main() -> int:
    for draw in (world, isolation, expansion):
        draw()
    return 0


if __name__ == "__main__":
    sys.exit(main())
