"""YAML loading that remembers where every value came from, within limits.

Every YAML fleet reads from its users (specs, template parameter defaults, rendered templates,
`--set` values, world.yaml) goes through `load_yaml`.  It builds plain Python data straight from
the parser's events, with a map from each value's path (a tuple of keys and list indexes) to its
(line, column), so validation errors point at the exact place in the user's file.

What plain yaml.safe_load lets through and this refuses, each with its own message:
- duplicate keys (safe_load keeps the last one, which hides typos) and merge keys (`<<`);
- tags other than the core ones (`!!str`, `!!int`, `!!float`, `!!bool`, `!!null`, `!!seq`,
  `!!map`): fleet would silently ignore them;
- NaN and infinity, integers outside ROS's int64 and floats beyond the double range;
- more than MAX_DEPTH nested collections (libyaml's composer recurses in C and crashes the
  interpreter on deep nesting, so collections are built here from events, without recursion);
- aliases that refer to the collection they are in, and documents that aliases expand to more
  than MAX_VALUES values (an "alias bomb": a few hundred bytes that expand to gigabytes).
  An alias shares the anchored value instead of copying it, and adds its size to the count, so
  refusing a bomb costs no more than reading it;
- texts longer than MAX_TEXT_CHARS.
Timestamps (`2024-05-01`) stay strings, as ROS's own parameter parser reads them.

Parameter values are read as rcl reads them, not by YAML 1.1's rules (fleet.spec.rcl_types):
a caller names the mappings that hold a node's parameters (`parameter_paths`), and every scalar
below them is typed from its source text by rcl_scalar (`1e-3` a double, `y` a bool, `1_000` a
string), quoted ones and `!!str` as strings; keys (node and parameter names) as the text they are
(YAML 1.1 would make `on: 1.0` a parameter named True).
Where rcl would read a value other than as its writer most likely meant, it is refused rather
than guessed: an empty value (rcl refuses it too), a plain `null` (a string to rcl), NaN and
infinity, a number beyond a double's range (a string to rcl), an integer beyond 64 bits (a
double to rcl), and tags other than `!!str` (which rcl ignores).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from fleet.errors import Location, SpecError
from fleet.spec.rcl_types import is_double_out_of_range, is_integer_text, rcl_scalar

# libyaml's parser when PyYAML was built with it: about ten times faster on big specs.
FAST_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
FAST_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)

# A place in a loaded document: the keys and list indexes leading to it, ("robots", 0, "name").
DocPath = tuple[Any, ...]
# A path of a document with None for "any key or index": ("robots", None, "parameters", None).
PathPattern = tuple[Any, ...]

MAX_TEXT_CHARS = 16 * 1024 * 1024
MAX_DEPTH = 64  # nested collections; a fleet spec needs about ten
MAX_VALUES = 2_000_000  # values of a document with its aliases expanded; the 20,000-robot benchmark spec has 350,000
MAX_NUMBER_CHARS = 100  # longer numbers are refused before Python converts them
INT64 = (-(2**63), 2**63 - 1)

_CORE = "tag:yaml.org,2002:"
_STR, _INT, _FLOAT, _MERGE, _MAP, _SEQ = (_CORE + name for name in ("str", "int", "float", "merge", "map", "seq"))
_SCALAR_TAGS = {_CORE + name for name in ("str", "int", "float", "bool", "null")}
_AS_TEXT = {_CORE + "timestamp", _CORE + "value", "!"}  # YAML 1.1 oddities ROS reads as strings
# The first characters of plain scalars PyYAML may give a type other than string (None: any).
_TYPED_FIRST = frozenset(FAST_LOADER.yaml_implicit_resolvers)
assert None not in _TYPED_FIRST
_CONSTRUCTOR = yaml.constructor.SafeConstructor()
_NO_KEY = object()
_RCL_NULLS = frozenset({"null", "Null", "NULL", "~"})
_QUOTED = ("'", '"')


class YamlError(SpecError):
    """YAML that cannot be read, or exceeds one of the limits above."""


class YamlSyntaxError(YamlError):
    """The text is not YAML; `problem` is the parser's own words (other readers word it their way)."""

    def __init__(self, problem: str, location: Location):
        super().__init__(f"YAML syntax error: {problem}", location)
        self.problem = problem


@dataclass
class SourceMap:
    """Where each path of a loaded document starts in its file."""

    file: str
    positions: dict[DocPath, tuple[int, int]] = field(default_factory=dict)
    key_positions: dict[DocPath, tuple[int, int]] = field(default_factory=dict)
    # The text the positions are read from when first asked for: places are shown only with
    # errors, warnings and --explain, so a document that is fine is read once, without them.
    text: str | None = field(default=None, repr=False)
    parameter_paths: tuple[PathPattern, ...] = ()  # read as load_yaml was told to read it

    def locate(self, path: DocPath, key: bool = False) -> Location:
        """The location of `path`, or of its closest ancestor that has one."""
        if self.text is not None:
            text, self.text = self.text, None
            _Composer(text, self, parameter_paths=self.parameter_paths).compose()
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


def read_input(path: Path, what: str) -> str:
    """The text of an input file named by the user, refused when it is not readable UTF-8 text
    or longer than MAX_TEXT_CHARS (read in bounded size, so /dev/zero cannot fill the memory)."""
    try:
        # Opened without waiting, then read as usual: a named pipe that nobody writes to reads as
        # empty instead of blocking for ever (a pipe being written, as from `<(...)`, still reads).
        descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        os.set_blocking(descriptor, True)
        with open(descriptor, "rb") as stream:
            data = stream.read(MAX_TEXT_CHARS + 1)
    except FileNotFoundError:
        raise YamlError(f"no such {what} file", Location(path)) from None
    except OSError as error:
        raise YamlError(f"cannot read {what} file: {error.strerror or error}", Location(path)) from None
    if len(data) > MAX_TEXT_CHARS:
        raise YamlError(f"{what} file is larger than {MAX_TEXT_CHARS} bytes", Location(path)) from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        line = data.count(b"\n", 0, error.start) + 1
        raise YamlError(
            f"cannot read {what} file: not UTF-8 text (byte {data[error.start]:#04x})", Location(path, line)
        ) from None


def load_yaml(text: str, file: str | Path, parameter_paths: tuple[PathPattern, ...] = ()) -> tuple[Any, SourceMap]:
    """Parse YAML text into plain data plus its SourceMap; every problem is a SpecError.
    Everything below a mapping at one of `parameter_paths` is a parameter value, typed as rcl types it."""
    source = SourceMap(str(file))
    data = _Composer(text, source, record=False, parameter_paths=parameter_paths).compose()
    source.text = text
    source.parameter_paths = parameter_paths
    return data, source


# A number with an exponent that YAML 1.1 reads as text: its floats need a '.' in the mantissa
# and a sign in the exponent (1.0e+9), so `1e9`, `1e+9`, `1.0e9` and `.5e3` are strings.
_TEXT_EXPONENT = re.compile(r"([+-]?)([0-9]*)(?:\.([0-9]*))?[eE]([+-]?)([0-9]+)")


def number_text_hint(value: object) -> str | None:
    """How to write the number `value` means when YAML read it as text (`1.0e9`), or None: the
    one rule every message about a number that is a string uses."""
    match = _TEXT_EXPONENT.fullmatch(value) if isinstance(value, str) else None
    if match is None or not (match[2] or match[3]):
        return None
    sign, whole, fraction, exponent_sign, exponent = match.groups()
    if fraction is not None and exponent_sign:
        return None  # a float to YAML too: it was quoted on purpose
    written = f"{sign}{whole or '0'}.{fraction or '0'}e{exponent_sign or '+'}{exponent}"
    return f"YAML reads {value} as text: write {written}"


def safe_load(text: str, file: str | Path = "<yaml>") -> Any:
    """Plain data from YAML text, with the limits and refusals of load_yaml but no SourceMap."""
    return _Composer(text, SourceMap(str(file)), record=False).compose()


def parse_parameter_value(text: str) -> Any:
    """A command-line parameter value read as rcl reads a value in a parameter file (`1e-3` a
    double, `[1, 2]` a list); raises ValueError saying why it is not one."""
    if not text.strip():
        return ""
    try:
        return _Composer(text, SourceMap("<value>"), record=False, parameter_paths=((),)).compose()
    except SpecError as error:
        raise ValueError(f"not a parameter value: {error.message}") from None


class _Frame:
    """A collection being built."""

    __slots__ = ("anchor", "container", "key", "path", "rcl", "size")

    def __init__(
        self,
        container: dict[Any, Any] | list[Any],
        path: DocPath | None,
        anchor: str | None,
        rcl: bool | tuple[PathPattern, ...],
    ):
        self.container = container
        self.path = path
        self.anchor = anchor
        self.key: Any = _NO_KEY  # a mapping's key waiting for its value
        self.size = 1  # values in it, itself included, aliases expanded
        # True: its values are parameter values; else the rest of the parameter paths that may
        # lead below it.
        self.rcl = rcl


def _below(rcl: bool | tuple[PathPattern, ...], key: Any) -> bool | tuple[PathPattern, ...]:
    """The `rcl` of a collection at `key` in one whose `rcl` is given."""
    if rcl is True or not rcl:
        return rcl
    assert not isinstance(rcl, bool)
    rest = tuple(pattern[1:] for pattern in rcl if pattern[0] is None or pattern[0] == key)
    return True if () in rest else rest


class _Composer:
    def __init__(
        self, text: str, source: SourceMap, record: bool = True, parameter_paths: tuple[PathPattern, ...] = ()
    ):
        self.text = text
        self.source = source
        self.record = record  # fill source.positions and key_positions
        self.anchors: dict[str, tuple[Any, int]] = {}  # anchor -> (value, size)
        self.values = 0
        self.parameter_paths: bool | tuple[PathPattern, ...] = True if () in parameter_paths else parameter_paths
        self.below: dict[tuple[Any, Any], bool | tuple[PathPattern, ...]] = {}  # _below's answers

    def compose(self) -> Any:
        if len(self.text) > MAX_TEXT_CHARS:
            raise YamlError(
                f"{len(self.text)} characters: larger than the {MAX_TEXT_CHARS} a YAML input may have",
                Location(self.source.file),
            )
        loader = FAST_LOADER(self.text)
        try:
            return self._build(loader)
        except yaml.MarkedYAMLError as error:
            mark = error.problem_mark or error.context_mark
            problem = error.problem or error.context or "invalid YAML"
            if "nesting depth" in problem:  # libyaml's own limit (0.2.6+), met while reading ahead
                raise _too_deep(self._location(mark)) from None
            raise YamlSyntaxError(problem, self._location(mark)) from None
        except yaml.reader.ReaderError as error:
            line = self.text.count("\n", 0, error.position) + 1
            column = error.position - (self.text.rfind("\n", 0, error.position) + 1) + 1
            character = chr(error.character) if isinstance(error.character, int) else error.character
            raise YamlError(
                f"YAML syntax error: character {character!r} is not allowed in YAML",
                Location(self.source.file, line, column),
            ) from None
        except yaml.YAMLError as error:
            raise YamlError(f"YAML error: {error}", Location(self.source.file)) from None
        finally:
            loader.dispose()

    def _build(self, loader: Any) -> Any:
        # The hot loop of reading a big spec (one pass per event): kept flat, with locals.
        stack: list[_Frame] = []
        open_anchors: set[str] = set()
        root: Any = None
        documents = 0
        record = self.record
        get_event = loader.get_event
        while True:
            event = get_event()
            kind = type(event)
            if kind is yaml.ScalarEvent:
                self.values += 1
                if self.values > MAX_VALUES:
                    raise self._too_many(event, alias=False)
                value, size = event.value, 1
                rcl = stack[-1].rcl if stack else self.parameter_paths
                # Parameter values are typed as rcl types them; their keys (node and parameter
                # names) are text to rcl, as they are written (`on`, `no`, `5` stay names).
                if rcl is True and (not stack or type(stack[-1].container) is list or stack[-1].key is not _NO_KEY):
                    value = self._rcl_scalar(event)
                elif rcl is True and event.tag is None:
                    pass
                elif event.tag is not None or (event.implicit[0] and (not value or value[0] in _TYPED_FIRST)):
                    value = self._scalar(event, loader)  # anything but a plain string (see _scalar)
                if event.anchor is not None:
                    self.anchors[event.anchor] = (value, size)
                if record:
                    self._record(stack, event)
            elif kind is yaml.MappingStartEvent or kind is yaml.SequenceStartEvent:
                is_map = kind is yaml.MappingStartEvent
                if event.tag is not None and event.tag not in (_MAP if is_map else _SEQ, "!"):
                    raise self._tag_error(event)
                if len(stack) >= MAX_DEPTH:
                    raise _too_deep(self._location(event.start_mark))
                if stack and stack[-1].key is _NO_KEY and isinstance(stack[-1].container, dict):
                    raise YamlError("mapping keys must be plain scalars", self._location(event.start_mark))
                self.values += 1
                if self.values > MAX_VALUES:
                    raise self._too_many(event, alias=False)
                path = self._record(stack, event) if record else None
                if not stack:
                    rcl = self.parameter_paths
                else:
                    parent_frame = stack[-1]
                    rcl = parent_frame.rcl
                    if rcl is not True and rcl:
                        container = parent_frame.container
                        key = len(container) if type(container) is list else parent_frame.key
                        below = self.below.get((rcl, key))
                        if below is None:
                            below = self.below[(rcl, key)] = _below(rcl, key)
                        rcl = below
                stack.append(_Frame({} if is_map else [], path, event.anchor, rcl))
                if event.anchor is not None:
                    open_anchors.add(event.anchor)
                continue
            elif kind is yaml.MappingEndEvent or kind is yaml.SequenceEndEvent:
                frame = stack.pop()
                value, size = frame.container, frame.size
                if frame.anchor is not None:
                    open_anchors.discard(frame.anchor)
                    self.anchors[frame.anchor] = (value, size)
            elif kind is yaml.AliasEvent:
                if event.anchor in open_anchors:
                    raise YamlError(
                        f"alias *{event.anchor} refers to the collection it is in: an endless value",
                        self._location(event.start_mark),
                    )
                if event.anchor not in self.anchors:
                    raise YamlError(f"alias *{event.anchor} has no anchor before it", self._location(event.start_mark))
                value, size = self.anchors[event.anchor]
                self.values += size
                if self.values > MAX_VALUES:
                    raise self._too_many(event, alias=True)
                if record:
                    self._record(stack, event)
            elif kind is yaml.DocumentStartEvent:
                documents += 1
                if documents > 1:
                    raise YamlError(
                        "a second YAML document ('---'): give one document", self._location(event.start_mark)
                    )
                continue
            elif kind is yaml.StreamEndEvent:
                return root
            else:  # stream start, document end
                continue
            if not stack:
                root = value
                continue
            parent = stack[-1]
            parent.size += size
            container = parent.container
            if type(container) is list:
                container.append(value)
            elif parent.key is _NO_KEY:
                if type(value) is not str and not isinstance(value, (int, float)):  # bools are ints
                    raise YamlError("mapping keys must be plain scalars", self._location(event.start_mark))
                if value in container:
                    raise YamlError(f"duplicate key {value!r}", self._location(event.start_mark))
                if record and parent.path is not None:
                    mark = event.start_mark
                    self.source.key_positions[(*parent.path, value)] = (mark.line + 1, mark.column + 1)
                parent.key = value
            else:
                container[parent.key] = value
                parent.key = _NO_KEY

    def _record(self, stack: list[_Frame], event: Any) -> DocPath | None:
        """The path of the value `event` starts, noted with its position (None for a key)."""
        if not stack:
            path: DocPath = ()
        else:
            parent = stack[-1]
            if parent.path is None:
                return None
            if isinstance(parent.container, list):
                path = (*parent.path, len(parent.container))
            elif parent.key is _NO_KEY:
                return None
            else:
                path = (*parent.path, parent.key)
        if self.record:
            self.source.positions[path] = (event.start_mark.line + 1, event.start_mark.column + 1)
        return path

    def _too_many(self, event: Any, alias: bool) -> YamlError:
        problem = "aliases expand this document to" if alias else "this document has"
        return YamlError(
            f"{problem} more than {MAX_VALUES} values: too big for a fleet input", self._location(event.start_mark)
        )

    def _tag_error(self, event: Any) -> YamlError:
        tag = str(event.tag).replace(_CORE, "!!")
        return YamlError(
            f"YAML tag {tag} is not supported: fleet reads plain strings, numbers, booleans, null, lists and mappings",
            self._location(event.start_mark),
        )

    def _scalar(self, event: Any, loader: Any) -> Any:
        tag, text = event.tag, event.value
        if tag is None:
            # Quoted and block scalars are strings, and so are plain ones no implicit type starts
            # with (most names); the others are typed by PyYAML's resolver.
            if not event.implicit[0] or (text and text[0] not in _TYPED_FIRST):
                return text
            tag = loader.resolve(yaml.ScalarNode, text, event.implicit)
        if tag == _STR or tag in _AS_TEXT:
            return text
        if tag in (_FLOAT, _INT):
            return self._number(tag, text, event)
        if tag == _MERGE:
            raise YamlError("YAML merge keys (<<) are not supported in fleet specs", self._location(event.start_mark))
        if tag not in _SCALAR_TAGS:
            raise self._tag_error(event)
        try:  # bool and null
            return _CONSTRUCTOR.yaml_constructors[tag](_CONSTRUCTOR, yaml.ScalarNode(tag, text))
        except (yaml.constructor.ConstructorError, ValueError, KeyError):
            raise YamlError(
                f"{text!r} is not a valid {tag.replace(_CORE, '')}", self._location(event.start_mark)
            ) from None

    def _rcl_scalar(self, event: Any) -> Any:
        """A parameter value, typed as rcl types it (see the module's doc)."""
        tag, text = event.tag, event.value
        if tag == _STR or event.style in _QUOTED:
            if tag not in (None, _STR, "!"):
                raise self._rcl_tag_error(event)
            return text
        if tag not in (None, "!"):
            raise self._rcl_tag_error(event)
        if not text and not event.style:
            raise YamlError(
                'no value: rcl refuses an empty parameter value (write "" for an empty string)',
                self._location(event.start_mark),
            )
        if text in _RCL_NULLS and not event.style:
            raise YamlError(
                f'{text} is not a ROS parameter value: rcl would read the string "{text}" '
                "(quote it if that is meant, or remove the key)",
                self._location(event.start_mark),
            )
        value = rcl_scalar(text)
        if type(value) is str and is_double_out_of_range(text):
            raise YamlError(
                f"{text} is beyond the range of a double: rcl would read the string {text!r} "
                "(give a number a double holds, or quote it if the text is meant)",
                self._location(event.start_mark),
            )
        if type(value) is str or type(value) is bool:
            return value
        problem = None
        if len(text) > MAX_NUMBER_CHARS:
            problem = f"number of {len(text)} characters: too large (integers are 64-bit, floats doubles)"
        elif isinstance(value, float) and not math.isfinite(value):
            problem = f"{text}: NaN and infinity are not accepted, give a finite number"
        elif isinstance(value, float) and is_integer_text(text):
            problem = (
                f"integer {text} is outside the 64-bit range ROS integers have "
                f"(rcl would read a double: write {text}.0 if one is meant)"
            )
        if problem is not None:
            raise YamlError(problem, self._location(event.start_mark))
        return value

    def _rcl_tag_error(self, event: Any) -> YamlError:
        tag = str(event.tag).replace(_CORE, "!!")
        return YamlError(
            f"YAML tag {tag} on a parameter value: rcl ignores tags other than !!str, so write the value "
            'as it should be read (1.0 for a double, "1" for a string)',
            self._location(event.start_mark),
        )

    def _number(self, tag: str, text: str, event: Any) -> int | float:
        if len(text) > MAX_NUMBER_CHARS:
            raise YamlError(
                f"number of {len(text)} characters: too large (integers are 64-bit, floats doubles)",
                self._location(event.start_mark),
            )
        try:
            value: int | float = float(text) if tag == _FLOAT else int(text)  # the common spellings, fast
        except ValueError:  # YAML 1.1's others: 0x1f, 017, 1:30, .inf ...
            try:
                value = _CONSTRUCTOR.yaml_constructors[tag](_CONSTRUCTOR, yaml.ScalarNode(tag, text))
            except (yaml.constructor.ConstructorError, ValueError, IndexError):
                raise YamlError(
                    f"{text!r} is not a valid {tag.replace(_CORE, '')}", self._location(event.start_mark)
                ) from None
        if isinstance(value, float) and not math.isfinite(value):
            problem = (
                f"{text} is too large for a float (a double)"
                if math.isinf(value) and any(char.isdigit() for char in text)
                else f"{text}: NaN and infinity are not accepted, give a finite number"
            )
            raise YamlError(problem, self._location(event.start_mark))
        if isinstance(value, int) and not INT64[0] <= value <= INT64[1]:
            raise YamlError(
                f"integer {text} is outside the 64-bit range ROS integers have", self._location(event.start_mark)
            )
        return value

    def _location(self, mark: Any) -> Location:
        if mark is None:
            return Location(self.source.file)
        return Location(self.source.file, mark.line + 1, mark.column + 1)


def _too_deep(location: Location) -> YamlError:
    return YamlError(f"more than {MAX_DEPTH} nested lists and mappings: too deep for a fleet input", location)
