"""`fleet render`: expand a fleet spec into launch files and parameter files (pure, no network)."""

from __future__ import annotations

import contextlib
import gc
from enum import StrEnum
from pathlib import Path, PurePosixPath

import typer

from fleet.cli.options import SET_HELP

# The list of the files a render wrote, kept in its directory: the next render into it removes
# them first, so that a robot no longer in the spec (or a format no longer asked for) leaves no
# launch file behind for whoever launches everything under the directory.
RENDER_MANIFEST = ".fleet-render"


class Format(StrEnum):
    yaml = "yaml"
    py = "py"
    both = "both"


def register(app: typer.Typer) -> None:
    app.command("render")(render)


def render(
    spec: Path = typer.Argument(..., help="Fleet spec file, e.g. fleets/two_robots.yaml."),
    output: Path | None = typer.Option(
        None, "--output", "-o", help="Write launch and parameter files here: a new or empty directory, or a render's."
    ),
    format: Format = typer.Option(Format.both, "--format", help="Launch file format to write: yaml, py or both."),
    set_: list[str] = typer.Option([], "--set", help=SET_HELP),
    explain: str | None = typer.Option(None, "--explain", help="Show the layers of ROBOT.NODE.PARAM."),
    json: bool = typer.Option(False, "--json", help="Print machine-readable JSON instead of tables."),
) -> None:
    """Expand SPEC into per-robot namespaced launch descriptions and parameter files.

    Without -o, print what would be deployed: robots, agents, nodes and effective parameters.

    -o DIR: a new or empty directory, or one a render wrote (which lists its files in DIR/.fleet-render).

    The earlier render's files are removed first: robots gone from the spec leave nothing behind.

    Files fleet did not write are kept; a non-empty DIR without that list is refused.
    """
    from fleet.cli.output import console, print_json, print_warnings
    from fleet.cli.plan_view import explain_data, plan_data, print_explain, print_plan

    if output is not None:
        check_output_directory(output)
    expansion = load_and_expand(spec, set_)
    if explain is not None:
        data = explain_data(expansion, explain)
        # "effective" is only true if the node reads the value: a typo'd name or a node started
        # without the parameter file is warned about here too
        print_warnings(expansion.warnings)
        print_json(data) if json else print_explain(data, console())
        return
    if output is None:
        print_warnings(expansion.warnings)  # on stderr, as deploy's: the report stays what it is
        with paused_gc():
            print_json(plan_data(expansion)) if json else print_plan(expansion, console())
        return
    written = write_bundles(expansion, output, format.value)
    print_warnings(expansion.warnings)
    if json:
        print_json({"output": str(output), "files": [str(path) for path in written]})
    else:
        console().print(
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
    """-o names a directory fleet may write into (new, empty or an earlier render's), or a place
    where one can be made: refused before anything is done."""
    from fleet.errors import FleetError, Location

    for place in (output, *output.parents):
        if place.exists():
            if not place.is_dir():
                problem = "is a file" if place == output else f"cannot be made: {place} is a file"
                raise FleetError(f"output directory {problem}, not a directory", Location(output))
            break
    try:
        foreign = output.is_dir() and not (output / RENDER_MANIFEST).is_file() and any(output.iterdir())
    except OSError as error:
        raise FleetError(f"cannot read output directory: {error.strerror}", Location(output)) from None
    if foreign:
        raise FleetError(
            f"output directory is not empty and holds no earlier render (no {RENDER_MANIFEST}): "
            "give a new or empty directory",
            Location(output),
        )


def remove_earlier_render(output: Path) -> None:
    """Remove the files the earlier render into `output` listed, and the robot directories they
    leave empty. Only entries `<unit>/<file>` are followed: an edited list cannot reach outside."""
    manifest = output / RENDER_MANIFEST
    if not manifest.is_file():
        return
    for entry in manifest.read_text(encoding="utf-8").splitlines():
        path = PurePosixPath(entry)
        if len(path.parts) != 2 or path.is_absolute() or ".." in path.parts:
            continue
        unit = output / path.parts[0]
        if unit.is_symlink():
            continue
        file = unit / path.parts[1]
        if file.is_file() or file.is_symlink():
            file.unlink()
        with contextlib.suppress(OSError):  # gone already, or holding files fleet did not write
            unit.rmdir()


def write_bundles(expansion, output: Path, format: str) -> list[Path]:
    """Write every bundle into output/<unit>/, leaving out the launch format not asked for."""
    from fleet.errors import FleetError, Location

    left_out = {"yaml": ".launch.py", "py": ".launch.yaml", "both": None}[format]
    chosen = {
        bundle.name: {name for name in bundle.files if left_out is None or not name.endswith(left_out)}
        for bundle in expansion.bundles
    }
    written = [output / unit / name for unit, names in chosen.items() for name in sorted(names)]
    try:
        remove_earlier_render(output)
        # Listed before they are written: a render that stops half way is still removed by the next.
        output.mkdir(parents=True, exist_ok=True)
        listing = "".join(f"{path.relative_to(output).as_posix()}\n" for path in written)
        (output / RENDER_MANIFEST).write_text(f"# written by fleet render, removed by the next\n{listing}")
        for bundle in expansion.bundles:
            bundle.write(output / bundle.name, chosen[bundle.name], atomic=False)  # nothing runs from here
    except OSError as error:
        raise FleetError(f"cannot write {error.filename or output}: {error.strerror}", Location(output)) from None
    return written
