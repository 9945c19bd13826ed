"""Rendering launch templates safely.

Templates are Jinja2 in a sandboxed environment with StrictUndefined.  Every `{{ }}` value passes
through `yaml_literal` (the environment's finalize hook), which emits a quoted YAML/JSON literal:
a robot name or argument value containing quotes, newlines or YAML syntax comes out as one inert
string and can never add an action or a node to the launch file.

A rendering is also bounded: Jinja's sandbox stops unsafe attribute access and caps range(), but
a template could still repeat a string a billion times, raise a number to a million digits, ask
a filter to pad to a gigabyte, or loop without end.  Those are refused with the template's name
(_BoundedEnvironment), output past MAX_OUTPUT_CHARS is refused, and a rendering is stopped after
MAX_RENDER_SECONDS (on the main thread, where the CLI renders: the timer is a signal).

Whatever else goes wrong in rendering a template is the template's error too, with its line: a
user's template never ends fleet with a traceback.
"""

from __future__ import annotations

import difflib
import functools
import glob
import importlib.resources
import json
import math
import signal
import sys
import threading
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import FrameType
from typing import Any

import jinja2
from jinja2 import nodes
from jinja2.compiler import CodeGenerator, Frame
from jinja2.sandbox import ImmutableSandboxedEnvironment, safe_range

from fleet.errors import FleetError, Location, TemplateError
from fleet.expand.shared import SharedMark, SharedTopic, declare, merge
from fleet.rules import PARAMS_SUFFIX, TEMPLATE_SUFFIX, template_name_problem
from fleet.spec.yaml_source import MAX_TEXT_CHARS, YamlError, number_text_hint, read_input

DEFAULTS_SUFFIX = PARAMS_SUFFIX  # a template's parameter defaults, beside it
MAX_OUTPUT_CHARS = MAX_TEXT_CHARS  # a rendered launch file is read back as fleet's own input
MAX_RENDER_SECONDS = 5.0  # a real template renders in about a millisecond
MAX_POWER_BITS = 4096  # far beyond an int64 parameter, far below a number that takes seconds to make


def builtin_template_dirs() -> list[Path]:
    """The templates shipped with fleet: the package fleet.templates (the top-level templates/
    folder, installed as package data; an editable install maps it onto the checkout's folder)."""
    # Installed wheels are unpacked, so the package's resources are files in a directory.
    return [Path(str(importlib.resources.files("fleet.templates")))]


# Jinja's own globals by what they are, so a template printing one hears its name.
_GLOBAL_NAMES = {id(value): name for name, value in {**jinja2.defaults.DEFAULT_NAMESPACE, "range": safe_range}.items()}


class LaunchBool(str):
    """A boolean launch argument's value as launch files spell it, "true" or "false", which a
    template's `{% if arg("enable_x", true) %}` (around a share(...), say) reads as the boolean
    it is: as plain text, "false" would hold there too."""

    def __bool__(self) -> bool:
        return self == "true"


def yaml_literal(value: Any) -> str:
    """A value as a YAML flow literal that parses back to exactly that value."""
    if isinstance(value, jinja2.Undefined):
        str(value)  # StrictUndefined raises UndefinedError with the variable's name
    if isinstance(value, SharedMark):  # share(...) declares, prints nothing
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise TypeError(f"cannot emit non-finite number {value!r}")
        return repr(value)
    if isinstance(value, str):
        # JSON strings are YAML double-quoted scalars; ensure_ascii escapes line separators too.
        return json.dumps(value, ensure_ascii=True)
    if isinstance(value, (list, tuple, dict)):
        # JSON would write a non-finite number as NaN or Infinity, which YAML reads as text.
        for number in _floats_in(value):
            yaml_literal(number)
        return json.dumps(value, ensure_ascii=True)
    if callable(value):  # Jinja's globals (namespace, range, dict, ...), arg, share, a macro, a method
        name = _GLOBAL_NAMES.get(id(value)) or getattr(value, "__name__", None) or getattr(value, "name", None)
        raise TypeError(
            f"'{name or type(value).__name__}' is a function, not a value: it cannot be printed into a launch "
            "file (print data such as robot.name, or call it)"
        )
    raise TypeError(f"cannot emit a value of type {type(value).__name__} into a launch file")


def _floats_in(value: Any) -> Iterator[float]:
    if isinstance(value, float):
        yield value
    elif isinstance(value, (list, tuple)):
        for item in value:
            yield from _floats_in(item)
    elif isinstance(value, dict):
        for item in (*value.keys(), *value.values()):
            yield from _floats_in(item)


def argument_problem(value: Any, default: Any) -> str | None:
    """Why `value` cannot be given for a launch argument whose default in the template is
    `default` (the default says what the launch file does with it), or None."""
    if isinstance(default, bool):
        if isinstance(value, bool) or (isinstance(value, str) and value.lower() in ("true", "false")):
            return None
        return f"is true or false (its default is {yaml_literal(default)}), got {value!r}"
    if isinstance(default, int):
        if isinstance(value, int) and not isinstance(value, bool):
            return None
        return f"is an integer (its default is {default}), got {value!r}"
    if isinstance(default, float):
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return None
        hint = number_text_hint(value)
        return f"is a number (its default is {default!r}), got {value!r}" + (f" ({hint})" if hint else "")
    return None  # text: any value is written as text


class _TooCostly(jinja2.exceptions.SecurityError):
    """A rendering asked for more than a launch file could ever need."""


class _RenderTimeout(Exception):
    pass


def _count_problem(value: Any) -> str | None:
    """Why a number given to a filter, function or repetition is too large to be a size, or None."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > MAX_OUTPUT_CHARS:
        return f"a count or width of {value} is larger than a launch file can be ({MAX_OUTPUT_CHARS} characters)"
    return None


def _bounded(function: Callable[..., Any]) -> Callable[..., Any]:
    """A filter or test that refuses sizes no launch file needs before doing the work."""

    @functools.wraps(function)  # keeps Jinja's pass_context/pass_environment markers
    def checked(*args: Any, **kwargs: Any) -> Any:
        for value in (*args, *kwargs.values()):
            if problem := _count_problem(value):
                raise _TooCostly(problem)
        return function(*args, **kwargs)

    return checked


def _power_bits(base: Any, exponent: Any) -> int:
    """About how many bits `base ** exponent` has (0 for what cannot grow: floats, 0, 1, -1, negative powers)."""
    if not (isinstance(base, int) and isinstance(exponent, int)) or abs(base) < 2 or exponent < 1:
        return 0
    return exponent * (abs(base).bit_length() - 1)


class _CodeGenerator(CodeGenerator):
    """Jinja's compiler, able to write every number a template holds into Python source.

    Jinja writes a constant of the template (a literal such as 1e400, or one it works out while
    compiling, such as 'nan'|float or [-1e400]) into the Python it compiles the template to as
    Python prints it: inf, nan, [-inf].  Python has no such names, so rendering failed with a
    NameError; defined at the top of the compiled module, they are those numbers again."""

    def visit_Template(self, node: nodes.Template, frame: Frame | None = None) -> None:
        self.writeline("from math import inf, nan")
        super().visit_Template(node, frame)


class _BoundedEnvironment(ImmutableSandboxedEnvironment):
    code_generator_class = _CodeGenerator
    intercepted_binops = frozenset({"*", "**"})

    def __init__(self, **options: Any) -> None:
        super().__init__(**options)
        self.filters = {name: _bounded(function) for name, function in self.filters.items()}

    def call_binop(self, context: jinja2.runtime.Context, operator: str, left: Any, right: Any) -> Any:
        if operator == "**" and _power_bits(left, right) > MAX_POWER_BITS:
            raise _TooCostly(f"{left} ** {right} has more than {MAX_POWER_BITS} bits")
        if operator == "*":
            for count, other in ((left, right), (right, left)):
                repeated = isinstance(count, int) and isinstance(other, (str, list, tuple))
                if repeated and count * len(other) > MAX_OUTPUT_CHARS:
                    raise _TooCostly(f"{len(other)} items repeated {count} times are larger than a launch file can be")
        return super().call_binop(context, operator, left, right)

    def call(self, __context: jinja2.runtime.Context, __obj: Any, *args: Any, **kwargs: Any) -> Any:
        for value in (*args, *kwargs.values()):
            if problem := _count_problem(value):
                raise _TooCostly(problem)
        return super().call(__context, __obj, *args, **kwargs)


@contextmanager
def _time_limit(seconds: float) -> Iterator[None]:
    """Interrupt the block after `seconds` (a signal, so only on the main thread; elsewhere no limit)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(signum: int, frame: object) -> None:
        raise _RenderTimeout

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _render_bounded(template: jinja2.Template, context: dict[str, Any], seconds: float) -> str:
    """The template's text, refused past MAX_OUTPUT_CHARS or `seconds`."""
    chunks: list[str] = []
    size = 0
    with _time_limit(seconds):
        for chunk in template.generate(context):
            size += len(chunk)
            if size > MAX_OUTPUT_CHARS:
                raise _TooCostly(f"its output is larger than {MAX_OUTPUT_CHARS} characters")
            chunks.append(chunk)
    return "".join(chunks)


class _TemplateLoader(jinja2.FileSystemLoader):
    """Jinja's file loader, reading each template (and each file one includes) as fleet reads every
    input file (`read_input`): one that is not UTF-8, or larger than the limit, is refused with its
    file and line, not with Python's words for a failed decode."""

    def get_source(self, environment: jinja2.Environment, template: str) -> tuple[str, str, Callable[[], bool]]:
        pieces = jinja2.loaders.split_template_path(template)  # refuses "..": never outside the directories
        for directory in self.searchpath:
            path = Path(directory, *pieces)
            if path.is_file():
                try:
                    text = read_input(path, "template")
                except YamlError as error:
                    raise TemplateError(error.message, error.location) from None
                return text, str(path), lambda: True  # read once: auto_reload is off
        raise jinja2.TemplateNotFound(template)


@dataclass
class RenderedTemplate:
    text: str
    template_file: Path
    arguments_asked: dict[str, Any] = field(default_factory=dict)  # arg(name, default) calls
    shared: list[SharedTopic] = field(default_factory=list)  # share(...) calls, one per topic


class TemplateSet:
    """The template directories a spec can use: its own first, then the built-in ones."""

    def __init__(self, directories: list[Path], render_seconds: float = MAX_RENDER_SECONDS):
        self.directories = [Path(d) for d in directories]
        self.render_seconds = render_seconds
        self._environment = _BoundedEnvironment(
            loader=_TemplateLoader([str(d) for d in self.directories]),
            undefined=jinja2.StrictUndefined,
            finalize=yaml_literal,
            autoescape=False,
            keep_trailing_newline=True,
            trim_blocks=True,
            lstrip_blocks=True,
            auto_reload=False,  # one expansion reads each template once
        )
        self._found: dict[str, Path | None] = {}
        self._identity_only: dict[str, bool] = {}

    def find(self, name: str) -> Path | None:
        if name not in self._found:
            self._found[name] = self._find(name)
        return self._found[name]

    def _find(self, name: str) -> Path | None:
        if template_name_problem(name):  # a path, not a name: never looked up
            return None
        for directory in self.directories:
            candidate = directory / f"{name}{TEMPLATE_SUFFIX}"
            if candidate.is_file():
                return candidate
        return None

    def not_found(self, name: str, where: Location) -> TemplateError:
        searched = ", ".join(str(d) for d in self.directories) or "no directories"
        known = sorted(
            {
                path.name.removesuffix(TEMPLATE_SUFFIX)
                for d in self.directories
                for path in d.glob(f"*{TEMPLATE_SUFFIX}")
            }
        )
        guess = difflib.get_close_matches(name, known, n=1)
        hint = f"; did you mean {guess[0]!r}?" if guess else (f"; templates there: {', '.join(known)}" if known else "")
        return TemplateError(
            f"template {name!r} not found (looked for {name}{TEMPLATE_SUFFIX} in {searched}){hint}", where
        )

    def identity_only(self, name: str) -> bool:
        """True when template `name` uses the robot only to print `{{ robot.name }}`,
        `{{ robot.namespace }}` and `{{ params_file }}` as they are: then every robot's rendering
        is one rendering with its own identity put in place of another's (names and namespaces
        print as themselves in quotes).  Judged from the syntax tree, conservatively: anything
        that could read the robot otherwise (a condition, a filter, another template) says no."""
        if name not in self._identity_only:
            path = self.find(name)
            try:
                source = path.read_text(encoding="utf-8") if path else None
                tree = self._environment.parse(source) if source is not None else None
            except (OSError, UnicodeDecodeError, jinja2.TemplateSyntaxError):
                tree = None  # rendering reports the problem
            self._identity_only[name] = tree is not None and _prints_identity_only(tree)
        return self._identity_only[name]

    def defaults_file(self, name: str) -> Path | None:
        template = self.find(name)
        if template is None:
            return None
        candidate = template.with_name(f"{name}{DEFAULTS_SUFFIX}")
        return candidate if candidate.is_file() else None

    def misnamed_defaults(self, name: str) -> Path | None:
        """A file beside template `name`, without its parameter defaults, that looks meant as them
        but is not read (`dd.params.yml`, `dd.param.yaml`, `dd_params.yaml`, `dd.yaml`): only
        `<name>.params.yaml` is.  Another template's defaults (`dd_2.params.yaml`) are not one."""
        template = self.find(name)
        if template is None or self.defaults_file(name) is not None:
            return None
        for path in sorted(template.parent.glob(f"{glob.escape(name)}?*")):
            rest = path.name[len(name) :].lower()
            if path.name.endswith(DEFAULTS_SUFFIX) or not rest.endswith((".yaml", ".yml")) or rest[0] not in "._-":
                continue
            if rest in (".yaml", ".yml") or "param" in rest:
                return path
        return None

    def render(
        self, name: str, context: dict[str, Any], arguments: dict[str, Any], where: Location
    ) -> RenderedTemplate:
        """Render template `name`; `arguments` are the launch argument values given for this unit."""
        path = self.find(name)
        if path is None:
            raise self.not_found(name, where)
        asked: dict[str, Any] = {}

        def arg(arg_name: str, default: Any) -> str:
            asked[arg_name] = default
            value = arguments.get(arg_name, default)
            # Launch arguments are strings; booleans in the ROS launch spelling.
            return LaunchBool("true" if value else "false") if isinstance(value, bool) else str(value)

        shared: list[SharedTopic] = []
        namespace = context.get("robot", {}).get("namespace", "/")

        def share(
            topic: Any,
            type: Any,  # the template's word for it
            robot: Any = "both",
            reliability: Any = "reliable",
            durability: Any = "volatile",
            depth: Any = 10,
        ) -> SharedMark:
            declared = declare(topic, type, namespace, robot, reliability, durability, depth)
            shared.append(replace(declared, line=_calling_line(template)))
            return SharedMark()

        try:
            template = self._environment.get_template(path.name)  # the loader searches in the same order as find()
            text = _render_bounded(template, {**context, "arg": arg, "share": share}, self.render_seconds)
            shared = merge(shared)
        except FleetError:  # placed already (a template file the loader could not read)
            raise
        except jinja2.TemplateSyntaxError as error:
            raise TemplateError(
                f"template syntax error: {error.message}", Location(error.filename or path, error.lineno)
            ) from None
        except jinja2.UndefinedError as error:
            raise TemplateError(
                f"{error.message} (available: {', '.join([*sorted(context), 'arg', 'share'])})",
                Location(path, _template_line(error, path)),
            ) from None
        except _RenderTimeout:
            raise TemplateError(
                f"template took more than {self.render_seconds:g} s to render (a loop without end?)", Location(path)
            ) from None
        except _TooCostly as error:
            raise TemplateError(
                f"template asks for too much: {error}", Location(path, _template_line(error, path))
            ) from None
        except jinja2.exceptions.SecurityError as error:
            raise TemplateError(
                f"template does something unsafe: {error}", Location(path, _template_line(error, path))
            ) from None
        except jinja2.TemplateNotFound as error:
            raise TemplateError(
                f"template includes {error.name!r}, which is not in the templates directories",
                Location(path, _template_line(error, path)),
            ) from None
        except RecursionError:
            raise TemplateError("template includes or calls itself without end", Location(path)) from None
        except (jinja2.TemplateError, TypeError, ValueError, ArithmeticError, LookupError) as error:
            # A call of arg() or share() with the wrong arguments names them as Python does: by
            # where they are defined, here.  The template knows them as arg() and share().
            message = str(error).replace(f"{TemplateSet.render.__qualname__}.<locals>.", "")
            raise TemplateError(message, Location(path, _template_line(error, path))) from None
        except Exception as error:  # none fleet expects (Jinja's own assert, say): still the template's
            raise TemplateError(
                f"template could not be rendered: {type(error).__name__}: {error}",
                Location(path, _template_line(error, path)),
            ) from None
        return RenderedTemplate(text=text, template_file=path, arguments_asked=asked, shared=shared)


_IDENTITY = {"robot": {"name", "namespace"}, "params_file": None}  # variable -> attributes printed
# Nodes through which a template could read its context other than by printing it.
_OPAQUE = (
    nodes.Include,
    nodes.Import,
    nodes.FromImport,
    nodes.Extends,
    nodes.Block,
    nodes.Macro,
    nodes.CallBlock,
    nodes.FilterBlock,
    nodes.AssignBlock,
)


def _prints_identity_only(tree: nodes.Template) -> bool:
    printed = set()
    for output in tree.find_all(nodes.Output):
        for child in output.nodes:
            if isinstance(child, nodes.Getattr) and isinstance(child.node, nodes.Name):
                if child.attr in (_IDENTITY.get(child.node.name) or ()):
                    printed.add(id(child.node))
            elif isinstance(child, nodes.Name) and child.name in _IDENTITY and _IDENTITY[child.name] is None:
                printed.add(id(child))
    if any(True for _ in tree.find_all(_OPAQUE)):
        return False
    return all(id(name) in printed for name in tree.find_all(nodes.Name) if name.name in _IDENTITY)


def _calling_line(template: jinja2.Template) -> int | None:
    """The line of `template` whose code called the function calling this one (share()), found
    among the frames of its compiled code, for errors found once the template has rendered."""
    frame: FrameType | None = sys._getframe(2)
    while frame is not None:
        if frame.f_code.co_filename == template.filename:
            return template.get_corresponding_lineno(frame.f_lineno)
        frame = frame.f_back
    return None


def _template_line(error: BaseException, path: Path) -> int | None:
    """The template line an error happened on (Jinja maps template frames to template lines)."""
    line = None
    for frame in traceback.extract_tb(error.__traceback__):
        if Path(frame.filename).resolve() == path.resolve():
            line = frame.lineno
    return line
