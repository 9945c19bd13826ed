"""YAML loading that remembers where every value came from.

PyYAML's composer gives nodes with start marks; we build plain Python data from them and a map
from each value's path (a tuple of keys and list indexes) to its (line, column), so validation
errors can point at the exact place in the user's file.  Duplicate keys are errors here: plain
yaml.safe_load silently keeps the last one, which hides typos in specs.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from fleet.errors import Location, SpecError

# libyaml's parser when PyYAML was built with it: about ten times faster on big specs.
FAST_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
FAST_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)

# A place in a loaded document: the keys and list indexes leading to it, ("robots", 0, "name").
DocPath = tuple[Any, ...]


def safe_load(text: str) -> Any:
    return yaml.load(text, Loader=FAST_LOADER)


@dataclass
class SourceMap:
    """Where each path of a loaded document starts in its file."""

    file: str
    positions: dict[DocPath, tuple[int, int]] = field(default_factory=dict)
    key_positions: dict[DocPath, tuple[int, int]] = field(default_factory=dict)

    def locate(self, path: DocPath, key: bool = False) -> Location:
        """The location of `path`, or of its closest ancestor that has one."""
        table = self.key_positions if key else self.positions
        probe = tuple(path)
        while True:
            if probe in table:
                line, column = table[probe]
                return Location(self.file, line, column)
            if probe in self.positions:
                line, column = self.positions[probe]
                return Location(self.file, line, column)
            if not probe:
                return Location(self.file)
            probe = probe[:-1]


class YamlSyntaxError(SpecError):
    """The text is not YAML; `problem` is the parser's own words (other readers word it their way)."""

    def __init__(self, problem: str, location: Location):
        super().__init__(f"YAML syntax error: {problem}", location)
        self.problem = problem


def load_yaml(text: str, file: str | Path) -> tuple[Any, SourceMap]:
    """Parse YAML text into plain data plus its SourceMap; syntax errors become SpecError."""
    source = SourceMap(str(file))
    try:
        node = yaml.compose(text, Loader=FAST_LOADER)
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        problem = error.problem or error.context or "invalid YAML"
        location = Location(file, mark.line + 1, mark.column + 1) if mark else Location(file)
        raise YamlSyntaxError(problem, location) from None
    except yaml.YAMLError as error:
        raise SpecError(f"YAML error: {error}", Location(file)) from None
    if node is None:
        return None, source
    return _Builder(source).build(node, ()), source


class _Builder:
    """Plain data from composed nodes, recording positions on the way."""

    def __init__(self, source: SourceMap):
        self.source = source
        self.constructor = yaml.constructor.SafeConstructor()

    def build(self, node: yaml.Node, path: DocPath) -> Any:
        return _construct(node, path, self.source, self)


def _construct(node: yaml.Node, path: DocPath, source: SourceMap, builder: _Builder) -> Any:
    source.positions[path] = (node.start_mark.line + 1, node.start_mark.column + 1)
    if isinstance(node, yaml.MappingNode):
        result: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                raise SpecError("YAML merge keys (<<) are not supported in fleet specs", _mark(source, key_node))
            key = _scalar(key_node, source, builder)
            if not isinstance(key, (str, int, float, bool)):
                raise SpecError("mapping keys must be plain scalars", _mark(source, key_node))
            if key in result:
                raise SpecError(f"duplicate key {key!r}", _mark(source, key_node))
            source.key_positions[(*path, key)] = (key_node.start_mark.line + 1, key_node.start_mark.column + 1)
            result[key] = _construct(value_node, (*path, key), source, builder)
        return result
    if isinstance(node, yaml.SequenceNode):
        return [_construct(item, (*path, index), source, builder) for index, item in enumerate(node.value)]
    return _scalar(node, source, builder)


def _scalar(node: yaml.Node, source: SourceMap, builder: _Builder) -> Any:
    if not isinstance(node, yaml.ScalarNode):
        raise SpecError("expected a plain value here", _mark(source, node))
    try:
        return builder.constructor.construct_object(node, deep=True)
    except yaml.constructor.ConstructorError as error:
        raise SpecError(f"bad value: {error.problem}", _mark(source, node)) from None


def _mark(source: SourceMap, node: yaml.Node) -> Location:
    return Location(source.file, node.start_mark.line + 1, node.start_mark.column + 1)


def parse_scalar(text: str) -> Any:
    """A command-line value parsed as one YAML scalar or flow collection (`0.8`, `true`, `[1, 2]`)."""
    try:
        return safe_load(text) if text.strip() else ""
    except yaml.YAMLError as error:
        raise ValueError(f"not a YAML value: {error}") from None
