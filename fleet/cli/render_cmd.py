"""`fleet render`: expand a fleet spec into launch files and parameter files (pure, no network)."""

from __future__ import annotations

import contextlib
import gc
import os
from collections.abc import Collection
from enum import StrEnum
from pathlib import Path, PurePosixPath

import typer

from fleet.cli.options import SET_HELP

# The list of the files a render wrote, kept in its directory: the next render into it removes
# them first, so that a robot no longer in the spec (or a format no longer asked for) leaves no
# launch file behind for whoever launches everything under the directory.
RENDER_MANIFEST = ".fleet-render"
MANIFEST_HEADER = "# written by fleet render, removed by the next"  # a list without it is not fleet's
GIVE_ANOTHER = "give a new or empty directory"


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

    A render is refused, leaving DIR as it was, if such a file is where it would write.
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
    from fleet.rules import directory_problem

    if problem := directory_problem(output):
        raise FleetError(f"output directory {problem}", Location(output))
    try:
        foreign = output.is_dir() and not (output / RENDER_MANIFEST).is_file() and any(output.iterdir())
    except OSError as error:
        raise FleetError(f"cannot read output directory: {error.strerror}", Location(output)) from None
    if foreign:
        raise FleetError(
            f"output directory is not empty and holds no earlier render (no {RENDER_MANIFEST}): {GIVE_ANOTHER}",
            Location(output),
        )


def write_bundles(expansion, output: Path, format: str) -> list[Path]:
    """Replace the earlier render in `output` with this one, leaving out the launch format not
    asked for. Everything that can refuse it is checked before anything is removed, so that a
    refused render leaves the directory as it was."""
    from fleet.errors import FleetError, Location

    left_out = {"yaml": ".launch.py", "py": ".launch.yaml", "both": None}[format]
    files = {
        output / bundle.name / name: bundle.files[name]
        for bundle in expansion.bundles
        for name in sorted(bundle.files)
        if left_out is None or not name.endswith(left_out)
    }
    try:
        earlier = earlier_render(output)
        check_room(output, earlier, files.keys())
    except OSError as error:
        raise FleetError(f"cannot read {error.filename or output}: {error.strerror}", Location(output)) from None
    failure: OSError | None = None
    try:
        remove_earlier_render(earlier)
        for path, text in files.items():
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")  # not atomically: nothing runs from here
    except OSError as error:  # a full disk, say: what was done stays done, and is listed
        failure = error
    finally:  # after a failure or Ctrl-C too
        # Written last: it names exactly fleet's files now on disk (earlier ones left, new ones, a
        # half-written one) for the next render to remove, and no file that is not there.
        try:
            if output.is_dir():
                record_render(output, [path for path in sorted(earlier | files.keys()) if os.path.lexists(path)])
        except OSError as error:
            # The earlier list would name removed files and miss new ones: no list is truthful.
            with contextlib.suppress(OSError):
                (output / RENDER_MANIFEST).unlink(missing_ok=True)
            failure = failure or error
    if failure is not None:
        raise FleetError(f"cannot write {failure.filename or output}: {failure.strerror}", Location(output))
    return list(files)


def earlier_render(output: Path) -> set[Path]:
    """The files the earlier render into `output` listed that are still there. Only entries
    `<unit>/<file>` are followed: an edited list cannot reach outside. A list that is not one fleet
    wrote is refused rather than guessed at, for the files it names would be removed."""
    from fleet.errors import FleetError, Location

    manifest = output / RENDER_MANIFEST
    if not manifest.is_file():
        return set()
    try:
        header, *entries = manifest.read_bytes().decode("utf-8").splitlines() or [""]
    except UnicodeDecodeError:
        raise FleetError(
            f"not a list fleet render wrote (not UTF-8 text): {GIVE_ANOTHER}", Location(manifest)
        ) from None
    if header != MANIFEST_HEADER:
        problem = f"its first line is not {MANIFEST_HEADER!r}"
        raise FleetError(f"not a list fleet render wrote ({problem}): {GIVE_ANOTHER}", Location(manifest))
    listed = set()
    for entry in entries:
        path = PurePosixPath(entry)
        if len(path.parts) != 2 or path.is_absolute() or ".." in path.parts:
            continue
        unit = output / path.parts[0]
        file = unit / path.parts[1]
        try:
            if not unit.is_symlink() and (file.is_file() or file.is_symlink()):
                listed.add(file)
        except OSError as error:  # a name too long, say: the list was edited
            raise FleetError(f"cannot follow {entry!r}: {error.strerror}", Location(manifest)) from None
    return listed


def check_room(output: Path, earlier: set[Path], files: Collection[Path]) -> None:
    """Each file goes where nothing is, or where the earlier render's file is (removed first), in a
    directory fleet can write: a file fleet did not write is never written over, and a symlink is
    never followed out of `output`."""
    from fleet.errors import FleetError, Location

    units = {path.parent for path in files}
    for place in [*sorted(units), *files]:
        if place in earlier or not (place.is_symlink() or place.exists()):
            continue
        if place in units and place.is_dir() and not place.is_symlink():
            continue
        kind = "symlink" if place.is_symlink() else "directory" if place.is_dir() else "file"
        raise FleetError(
            f"in the way of the render: a {kind} fleet did not write (move it, or give another directory)",
            Location(place),
        )
    made_in = next(place for place in (output, *output.parents) if place.exists())
    changed = {made_in, *(file.parent for file in earlier), *(unit for unit in units if unit.is_dir())}
    for directory in sorted(changed):
        if not os.access(directory, os.W_OK | os.X_OK):
            raise FleetError("cannot write into this directory (no permission, or read-only)", Location(directory))


def remove_earlier_render(earlier: set[Path]) -> None:
    """Remove the earlier render's files, and the directories they leave empty."""
    for file in sorted(earlier):
        file.unlink()
    for unit in {file.parent for file in earlier}:
        with contextlib.suppress(OSError):  # holding files fleet did not write
            unit.rmdir()


def record_render(output: Path, files: list[Path]) -> None:
    """List `files` in output/.fleet-render, replacing the earlier list in one step."""
    from fleet.files import write_atomic

    listing = "".join(f"{path.relative_to(output).as_posix()}\n" for path in files)
    # readable as the launch files beside it are (a temporary file is made owner-only)
    write_atomic(output / RENDER_MANIFEST, f"{MANIFEST_HEADER}\n{listing}", mode=0o644)
