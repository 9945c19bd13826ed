"""The two frontends' entities, with places: an action or attribute as written in YAML or XML.

launch reads both formats through one interface (launch.frontend.Entity); so does the reader
here.  The frontends differ in how they type attribute values, and that difference is kept:
launch_yaml takes the YAML value as it is (a quoted `'false'` stays a string), launch_xml has
only strings and converts them when an action asks for a type.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any
from xml.parsers import expat

from fleet.errors import LaunchFileError, Location, SpecError
from fleet.spec.yaml_source import MAX_DEPTH, SourceMap, YamlSyntaxError, load_yaml

YAML, XML = "yaml", "xml"


class Entity:
    """One action or sub-entity (`param`, `remap`, `env`, `arg`, `choice`, `keep`)."""

    frontend: str
    kind: str
    where: Location

    def attributes(self) -> dict[str, Any]:
        """Attribute name -> value as written (XML: always a string)."""
        raise NotImplementedError

    def where_of(self, name: str) -> Location:
        raise NotImplementedError

    def entities(self, name: str) -> list[Entity] | None:
        """The sub-entities written under `name` (a YAML list of mappings, XML child elements)."""
        raise NotImplementedError

    def children(self) -> list[Entity] | None:
        """The child actions (group, timer), or None when there is no list of them."""
        raise NotImplementedError


class _Place(Location):
    """A Location in a YAML file, found only when first read: finding places costs a second
    reading of the text, which a file that is fine (rendered by the thousand) never needs."""

    def __init__(self, source: SourceMap, path: tuple[Any, ...]):  # no dataclass fields set: see _found
        self._source, self._path = source, path
        self._location: Location | None = None

    def _found(self) -> Location:
        if self._location is None:
            self._location = self._source.locate(self._path, key=True)
        return self._location

    file = property(lambda self: self._found().file)
    line = property(lambda self: self._found().line)
    column = property(lambda self: self._found().column)


class YamlEntity(Entity):
    frontend = YAML

    def __init__(self, kind: str, body: Any, path: tuple[Any, ...], source: SourceMap):
        self.kind, self.body, self.path, self.source = kind, body, path, source

        self.where = _Place(source, path)

    def attributes(self) -> dict[str, Any]:
        return dict(self.body) if isinstance(self.body, dict) else {}

    def where_of(self, name: str) -> Location:
        return _Place(self.source, (*self.path, name))

    def entities(self, name: str) -> list[Entity] | None:
        items = self.body.get(name) if isinstance(self.body, dict) else None
        if items is None:
            return None
        if not isinstance(items, list) or not items or not all(isinstance(item, dict) for item in items):
            raise LaunchFileError(f"'{name}' of '{self.kind}' must be a list of mappings", self.where_of(name))
        return [YamlEntity(name, item, (*self.path, name, index), self.source) for index, item in enumerate(items)]

    def children(self) -> list[Entity] | None:
        if isinstance(self.body, list):
            return list(_yaml_actions(self.body, self.path, self.source))
        if isinstance(self.body, dict) and isinstance(self.body.get("children"), list):
            return list(_yaml_actions(self.body["children"], (*self.path, "children"), self.source))
        return None


def _yaml_actions(items: list[Any], path: tuple[Any, ...], source: SourceMap) -> Iterator[Entity]:
    for index, item in enumerate(items):
        if not isinstance(item, dict) or len(item) != 1:
            raise LaunchFileError(
                "each action is a mapping with exactly one key, the action type", source.locate((*path, index))
            )
        ((kind, body),) = item.items()
        if not isinstance(kind, str):
            raise LaunchFileError(f"unknown action '{kind}'", source.locate((*path, index)))
        yield YamlEntity(kind, body, (*path, index, kind), source)


def yaml_actions(text: str, file: str) -> list[Entity]:
    try:
        data, source = load_yaml(text, file)
    except YamlSyntaxError as problem:
        raise LaunchFileError(f"invalid YAML: {problem.problem}", problem.location) from None
    except SpecError as problem:
        raise LaunchFileError(f"invalid YAML: {problem.message}", problem.location) from None
    return yaml_document_actions(data, source, file)


def yaml_document_actions(data: Any, source: SourceMap, file: str) -> list[Entity]:
    """The actions of a YAML launch document already loaded (by load_yaml, with its SourceMap)."""
    if not isinstance(data, dict) or set(data) != {"launch"}:
        raise LaunchFileError("a launch file is a mapping with the single key 'launch'", Location(file, 1, 1))
    if not isinstance(data["launch"], list):
        raise LaunchFileError("'launch' must be a list of actions", source.locate(("launch",), key=True))
    return list(_yaml_actions(data["launch"], ("launch",), source))


class XmlEntity(Entity):
    frontend = XML

    def __init__(self, kind: str, attributes: dict[str, str], where: Location):
        self.kind, self.attrs, self.where = kind, attributes, where
        self.elements: list[XmlEntity] = []

    def attributes(self) -> dict[str, Any]:
        names: dict[str, Any] = dict(self.attrs)
        for element in self.elements:
            names.setdefault(element.kind, [])
        return names

    def where_of(self, name: str) -> Location:
        for element in self.elements:
            if element.kind == name:
                return element.where
        return self.where  # expat tells where an element starts, not where each attribute does

    def entities(self, name: str) -> list[Entity] | None:
        found: list[Entity] = [element for element in self.elements if element.kind == name]
        return found or None

    def children(self) -> list[Entity] | None:
        return list(self.elements)


def xml_actions(text: str, file: str) -> list[Entity]:
    parser = expat.ParserCreate()
    stack: list[XmlEntity] = []
    roots: list[XmlEntity] = []

    def start(tag: str, attributes: dict[str, str]) -> None:
        element = XmlEntity(tag, attributes, Location(file, parser.CurrentLineNumber, parser.CurrentColumnNumber + 1))
        if len(stack) >= MAX_DEPTH:  # the YAML frontend's bound: reading deeper recursed out of Python's stack
            raise LaunchFileError(f"more than {MAX_DEPTH} nested elements: too deep for a fleet input", element.where)
        (stack[-1].elements if stack else roots).append(element)
        stack.append(element)

    def end(tag: str) -> None:
        stack.pop()

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(text, True)
    except expat.ExpatError as problem:
        raise LaunchFileError(
            f"invalid XML: {expat.ErrorString(problem.code)}", Location(file, problem.lineno, problem.offset + 1)
        ) from None
    root = roots[0]
    if root.kind != "launch":
        raise LaunchFileError("an XML launch file has the root element <launch>", root.where)
    return list(root.elements)
