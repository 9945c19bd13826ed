"""Rendering launch templates safely.

Templates are Jinja2 in a sandboxed environment with StrictUndefined.  Every `{{ }}` value passes
through `yaml_literal` (the environment's finalize hook), which emits a quoted YAML/JSON literal:
a robot name or argument value containing quotes, newlines or YAML syntax comes out as one inert
string and can never add an action or a node to the launch file.
"""

from __future__ import annotations

import importlib.resources
import json
import math
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jinja2
from jinja2.sandbox import ImmutableSandboxedEnvironment

from fleet.errors import Location, TemplateError

TEMPLATE_SUFFIX = ".launch.yaml.j2"
DEFAULTS_SUFFIX = ".params.yaml"


def builtin_template_dirs() -> list[Path]:
    """The templates shipped with fleet: the package fleet.templates (the top-level templates/
    folder, installed as package data; an editable install maps it onto the checkout's folder)."""
    # Installed wheels are unpacked, so the package's resources are files in a directory.
    return [Path(str(importlib.resources.files("fleet.templates")))]


def yaml_literal(value: Any) -> str:
    """A value as a YAML flow literal that parses back to exactly that value."""
    if isinstance(value, jinja2.Undefined):
        str(value)  # StrictUndefined raises UndefinedError with the variable's name
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
        return json.dumps(value, ensure_ascii=True)
    raise TypeError(f"cannot emit a value of type {type(value).__name__} into a launch file")


@dataclass
class RenderedTemplate:
    text: str
    template_file: Path
    arguments_asked: dict[str, Any] = field(default_factory=dict)  # arg(name, default) calls


class TemplateSet:
    """The template directories a spec can use: its own first, then the built-in ones."""

    def __init__(self, directories: list[Path]):
        self.directories = [Path(d) for d in directories]
        self._environment = ImmutableSandboxedEnvironment(
            loader=jinja2.FileSystemLoader([str(d) for d in self.directories]),
            undefined=jinja2.StrictUndefined,
            finalize=yaml_literal,
            autoescape=False,
            keep_trailing_newline=True,
            trim_blocks=True,
            lstrip_blocks=True,
        )

    def find(self, name: str) -> Path | None:
        for directory in self.directories:
            candidate = directory / f"{name}{TEMPLATE_SUFFIX}"
            if candidate.is_file():
                return candidate
        return None

    def defaults_file(self, name: str) -> Path | None:
        template = self.find(name)
        if template is None:
            return None
        candidate = template.with_name(f"{name}{DEFAULTS_SUFFIX}")
        return candidate if candidate.is_file() else None

    def render(
        self, name: str, context: dict[str, Any], arguments: dict[str, Any], where: Location
    ) -> RenderedTemplate:
        """Render template `name`; `arguments` are the launch argument values given for this unit."""
        path = self.find(name)
        if path is None:
            searched = ", ".join(str(d) for d in self.directories) or "no directories"
            raise TemplateError(
                f"template {name!r} not found (looked for {name}{TEMPLATE_SUFFIX} in {searched})", where
            )
        asked: dict[str, Any] = {}

        def arg(arg_name: str, default: Any) -> str:
            asked[arg_name] = default
            value = arguments.get(arg_name, default)
            # Launch arguments are strings; booleans in the ROS launch spelling.
            return ("true" if value else "false") if isinstance(value, bool) else str(value)

        try:
            template = self._environment.get_template(path.name)  # the loader searches in the same order as find()
            text = template.render({**context, "arg": arg})
        except jinja2.TemplateSyntaxError as error:
            raise TemplateError(
                f"template syntax error: {error.message}", Location(error.filename or path, error.lineno)
            ) from None
        except jinja2.UndefinedError as error:
            raise TemplateError(
                f"{error.message} (available: {', '.join([*sorted(context), 'arg'])})",
                Location(path, _template_line(error, path)),
            ) from None
        except jinja2.exceptions.SecurityError as error:
            raise TemplateError(
                f"template does something unsafe: {error}", Location(path, _template_line(error, path))
            ) from None
        except TypeError as error:
            raise TemplateError(str(error), Location(path, _template_line(error, path))) from None
        return RenderedTemplate(text=text, template_file=path, arguments_asked=asked)


def _template_line(error: BaseException, path: Path) -> int | None:
    """The template line an error happened on (Jinja maps template frames to template lines)."""
    line = None
    for frame in traceback.extract_tb(error.__traceback__):
        if Path(frame.filename).resolve() == path.resolve():
            line = frame.lineno
    return line
