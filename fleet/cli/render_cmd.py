"""`fleet render`: expand a fleet spec into launch files and parameter files (pure, no network)."""

from __future__ import annotations

import contextlib
import gc
from enum import StrEnum
from pathlib import Path

import typer

from fleet.cli.options import SET_HELP


class Format(StrEnum):
    yaml = "yaml"
    py = "py"
    both = "both"


def register(app: typer.Typer) -> None:
    app.command("render")(render)


def render(
    spec: Path = typer.Argument(..., help="Fleet spec file, e.g. fleets/two_robots.yaml."),
    output: Path | None = typer.Option(None, "--output", "-o", help="Write launch and parameter files here."),
    format: Format = typer.Option(Format.both, "--format", help="Launch file format to write: yaml, py or both."),
    set_: list[str] = typer.Option([], "--set", help=SET_HELP),
    explain: str | None = typer.Option(None, "--explain", help="Show the layers of ROBOT.NODE.PARAM."),
    json: bool = typer.Option(False, "--json", help="Print machine-readable JSON instead of tables."),
) -> None:
    """Expand SPEC into per-robot namespaced launch descriptions and parameter files.

    Without -o, print what would be deployed: robots, agents, nodes and effective parameters.
    """
    from fleet.cli.output import console, labelled, print_json
    from fleet.cli.plan_view import explain_data, plan_data, print_explain, print_plan

    if output is not None:
        check_output_directory(output)
    expansion = load_and_expand(spec, set_)
    if explain is not None:
        data = explain_data(expansion, explain)
        print_json(data) if json else print_explain(data, console())
        return
    if output is None:
        with paused_gc():
            print_json(plan_data(expansion)) if json else print_plan(expansion, console())
        return
    written = write_bundles(expansion, output, format.value)
    if json:
        print_json({"output": str(output), "files": [str(path) for path in written]})
    else:
        out = console()
        for warning in expansion.warnings:
            out.print(labelled("warning:", "yellow", warning))
        out.print(
            f"wrote {len(written)} files for {len(expansion.robots)} robots"
            + (" and the world" if expansion.bundle("world") else "")
            + f" to {output}/"
        )


def load_and_expand(spec: Path, sets: list[str]):
    """Validate and expand; every problem raises before anything is written or sent."""
    from fleet.expand import expand_fleet
    from fleet.spec import load_spec

    with paused_gc():
        return expand_fleet(load_spec(spec), sets)


@contextlib.contextmanager
def paused_gc():
    """Python's cyclic garbage collector paused: expanding a big fleet makes millions of objects
    that all live until the command ends, and the collector's passes over them cost a fifth of
    the time while finding nothing to free."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def check_output_directory(output: Path) -> None:
    """-o names a directory, or a place where one can be made: refused before anything is done."""
    from fleet.errors import FleetError, Location

    for place in (output, *output.parents):
        if place.exists():
            if not place.is_dir():
                problem = "is a file" if place == output else f"cannot be made: {place} is a file"
                raise FleetError(f"output directory {problem}, not a directory", Location(output))
            return


def write_bundles(expansion, output: Path, format: str) -> list[Path]:
    """Write every bundle into output/<unit>/, leaving out the launch format not asked for."""
    from fleet.errors import FleetError, Location

    left_out = {"yaml": ".launch.py", "py": ".launch.yaml", "both": None}[format]
    written = []
    for bundle in expansion.bundles:
        names = {name for name in bundle.files if left_out is None or not name.endswith(left_out)}
        directory = output / bundle.name
        try:
            bundle.write(directory, names, atomic=False)  # nothing runs from a render directory
        except OSError as error:
            raise FleetError(
                f"cannot write {error.filename or directory}: {error.strerror}", Location(output)
            ) from None
        written += [directory / name for name in sorted(names)]
    return written
