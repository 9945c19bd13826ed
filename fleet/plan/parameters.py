"""The ROS parameters a bundle deploys, read from its params files, and how two bundles' differ (pure)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fleet.errors import SpecError
from fleet.rules import PARAMS_SUFFIX

ParameterValues = dict[str, dict[str, Any]]  # node's name as in the file (its fqn) -> parameter -> value


@dataclass(frozen=True)
class ParameterChange:
    node: str  # as its params file names it: /robot2/controller
    name: str  # nested names joined with dots, as rcl names them: limits.max_speed
    old: Any = None  # None: the parameter is new
    new: Any = None  # None: the parameter is gone

    def __str__(self) -> str:
        from fleet.spec.rcl_types import value_text  # not at the top: fleet.spec reads YAML, status does not

        where = f"{self.node.rsplit('/', 1)[-1]}.{self.name}"
        if self.old is None:
            return f"{where} = {value_text(self.new)} (new)"
        if self.new is None:
            return f"{where} removed (was {value_text(self.old)})"
        return f"{where} {value_text(self.old)} -> {value_text(self.new)}"


def bundle_parameters(files: dict[str, str]) -> ParameterValues:
    """Every node's parameters in the bundle's params files (fleet writes one per robot; several
    are merged in name order).  A file that is not valid YAML adds nothing: it came from fleet's
    own expansion, and the agent is the one to refuse it."""
    # Imported here: fleet.plan is on `fleet status`'s path, which reads no YAML.
    from fleet.spec.params import ParameterNameClash, flatten
    from fleet.spec.yaml_source import safe_load

    values: ParameterValues = {}
    for name, text in sorted(files.items()):
        if not name.endswith(PARAMS_SUFFIX):
            continue
        try:
            data = safe_load(text, name)  # from a message: with the limits of every input
        except SpecError:
            continue
        for node, section in data.items() if isinstance(data, dict) else ():
            parameters = section.get("ros__parameters") if isinstance(section, dict) else None
            if not isinstance(parameters, dict):
                continue
            try:
                flat = flatten(parameters)
            except ParameterNameClash:  # as above: not fleet's to refuse here
                continue
            values.setdefault(str(node), {}).update((name, value) for name, (_, value) in flat.items())
    return values


def parameter_changes(old_files: dict[str, str], new_files: dict[str, str]) -> list[ParameterChange]:
    """What changes, parameter by parameter, from one bundle's params files to another's."""
    old, new = bundle_parameters(old_files), bundle_parameters(new_files)
    changes = []
    for node in sorted(old.keys() | new.keys()):
        before, after = old.get(node, {}), new.get(node, {})
        for name in sorted(before.keys() | after.keys()):
            if before.get(name) != after.get(name) or (name in before) != (name in after):
                changes.append(ParameterChange(node, name, before.get(name), after.get(name)))
    return changes
